/*
 * The fitted force model on the chip: PostureModel.predict (pressure-only) in 32-bit floats.
 * The equations and their reasons are the Python's (labcli/papers/takuma2014/models/posture.py,
 * routes.py, takuma.py); this is their arithmetic, with the model's numbers from MODEL_HEADER
 * (labcli export-model) kept in flash.
 *
 * Posture form:  u = P0/P - 1; deflections from the angle terms of u; theta1 from its own
 * terms; torques from the pressure drops, their products with the deflections and the
 * deflections; forces as the posterior mean given the torques at theta0 + dtheta and the fit
 * loads' spread (the gain form P J (J^T P J + S)^-1); the forces' covariance adds the
 * deflections' through dF/d(dtheta), in closed form (the host takes central differences: four
 * more evaluations of the forces, which would double the chip's time).
 * With the sleeves' friction terms (MODEL_HAS_FRICTION, labcli fit --friction-terms) the torque
 * design has per actuator pair erf(m / w) - erf(m_in / w): its motion under the load m (the
 * outside pair's dtheta1, the inside pair's dtheta1 + dtheta2) and into the baseline m_in (from
 * the caller's history; 0 where unknown), w the fade with the estimated motion's error
 * (MODEL_FRICTION_WIDTH, posture.py's friction_columns); erf by model_erf, once a pair per
 * estimate (the forces and their gradient share its value and slope) and once a pair per baseline.
 * Paper form (Eqs. 34-37) where a quantity is routed to it or blended with it: angles by
 * arcsin, forces through (J^-1)^T at the estimated angles, standard errors from the held-out
 * variance plus x^T C x.
 */
#include <math.h>

#include "model.h"

#include MODEL_HEADER

#ifndef MODEL_HAS_FRICTION
#define MODEL_HAS_FRICTION 0 /* a header of before the friction terms */
#endif
#ifndef MODEL_HAS_HELD_OUT
#define MODEL_HAS_HELD_OUT 0 /* a header of before the direction term: no MODEL_HELD_OUT_VAR */
#endif

#define ROUTE_POSTURE 0
#define ROUTE_PAPER 1
#define ROUTE_BLEND 2

const char model_id[] = MODEL_ID;
const char model_quantities[] = MODEL_QUANTITIES;
const char model_channel_names[] = MODEL_CHANNEL_NAMES;

float model_si(uint8_t channel, float counts)
{
    return MODEL_GAIN[channel] * (counts - MODEL_ZERO[channel]);
}

uint8_t model_p_channel(uint8_t k)
{
    return MODEL_P_CHANNEL[k];
}

uint8_t model_pot_channel(uint8_t j)
{
    return MODEL_POT_CHANNEL[j];
}

float model_limit(uint8_t q)
{
    return MODEL_LIMIT[q];
}

float model_baseline_min_counts(uint8_t k)
{
    return MODEL_BASELINE_MIN_COUNTS[k];
}

uint8_t model_uses_history(void)
{
    return MODEL_HAS_FRICTION;
}

#if MODEL_HAS_FRICTION || !defined(__AVR__) /* the chip keeps it only for the friction terms */
float model_erf(float x, float *slope)
{
    float a = fabsf(x), t = 1.0f / (1.0f + 0.3275911f * a), g = expf(-a * a);
    float y = 1.0f - t * (0.254829592f + t * (-0.284496736f + t * (1.421413741f + t * (-1.453152027f + t * 1.061405429f)))) * g;
    if (slope)
        *slope = 1.12837917f * g; /* 2 / sqrt(pi) exp(-x^2) */
    return x < 0.0f ? -y : y;
}
#endif

#if MODEL_HAS_POSTURE
/* x^T M x for a symmetric n x n M in flash: the diagonal and twice the upper triangle. */
static float quad(const __flash float *M, const float *x, uint8_t n)
{
    float s = 0.0f;
    for (uint8_t i = 0; i < n; i++) {
        float row = 0.5f * M[i * n + i] * x[i];
        for (uint8_t j = i + 1; j < n; j++)
            row += M[i * n + j] * x[j];
        s += x[i] * row;
    }
    return 2.0f * s;
}

/* Terms (i, j) of u: u_i (j < 0) or u_i u_j. */
static void angle_features(const __flash int8_t (*term)[2], uint8_t n, const float *u, float *x)
{
    for (uint8_t k = 0; k < n; k++)
        x[k] = term[k][1] < 0 ? u[term[k][0]] : u[term[k][0]] * u[term[k][1]];
}

#endif

/* cos and sin of theta1 and theta1 + theta2: what J needs, computed once per posture. */
struct trig {
    float c1, s1, c12, s12;
};

#if MODEL_HAS_POSTURE
static void trig_of(float t1, float t2, struct trig *t)
{
    t->c1 = cosf(t1);
    t->s1 = sinf(t1);
    t->c12 = cosf(t1 + t2);
    t->s12 = sinf(t1 + t2);
}
#endif

/* J(theta) of Section 2.2.2 (tau = J^T F). */
static void jacobian(const struct trig *t, float J[2][2])
{
    J[0][0] = -MODEL_H2 * t->c1 - MODEL_H3 * t->c12;
    J[0][1] = -MODEL_H3 * t->c12;
    J[1][0] = -MODEL_H2 * t->s1 - MODEL_H3 * t->s12;
    J[1][1] = -MODEL_H3 * t->s12;
}

#if MODEL_HAS_POSTURE
/* The inverse of a symmetric 2 x 2 matrix; its pseudo-inverse where it is singular. */
static void inv2(const float A[2][2], float R[2][2])
{
    float det = A[0][0] * A[1][1] - A[0][1] * A[1][0];
    float tr = A[0][0] + A[1][1];
    if (fabsf(det) > 1e-12f * tr * tr) {
        R[0][0] = A[1][1] / det;
        R[1][1] = A[0][0] / det;
        R[0][1] = R[1][0] = -A[0][1] / det;
        return;
    }
    /* Rank one (or zero): A = tr * v v^T, its pseudo-inverse v v^T / tr. */
    float k = tr > 0.0f ? 1.0f / (tr * tr) : 0.0f;
    for (uint8_t i = 0; i < 2; i++)
        for (uint8_t j = 0; j < 2; j++)
            R[i][j] = A[i][j] * k;
}


/* The friction terms at one posture, per pair (term 14 + p): erf(m / w) less the baseline's
 * erf(m_in / w), and its slope by the pair's motion, 2 exp(-(m/w)^2) / (sqrt(pi) w). */
struct friction {
    float v[2], slope[2];
};

#if MODEL_HAS_FRICTION
/* Pair p's erf(m_in / w) of the motion into the baseline (moved; 0: none, the term reads 0): one
 * erf when the motion changes (a new baseline), kept for every estimate of that baseline. */
static float baseline_erf(uint8_t p, const float *moved)
{
    static float m_was[2] = {NAN, NAN}, erf_was[2];
    if (!moved)
        return 0.0f;
    float m = p ? moved[0] + moved[1] : moved[0];
    if (!(m == m_was[p])) {
        m_was[p] = m;
        erf_was[p] = model_erf(m / MODEL_FRICTION_WIDTH[p], 0);
    }
    return erf_was[p];
}

/* Both pairs' terms at deflections dth (the inside pair moves with both joints): one erf a pair
 * for the value and the slope, which the forces and their gradient then share. */
static void friction_of(const float *dth, const float *moved, struct friction *f)
{
    for (uint8_t p = 0; p < 2; p++) {
        float w = MODEL_FRICTION_WIDTH[p], slope;
        f->v[p] = model_erf((p ? dth[0] + dth[1] : dth[0]) / w, &slope) - baseline_erf(p, moved);
        f->slope[p] = slope / w;
    }
}
#endif

/* The torque design's columns MODEL_TORQUE_TERM of the 14: dP (4), dP_j dtheta_l (8), dtheta (2),
 * and the friction terms (2, fr: friction_of at dth); with d (>= 0), their derivatives by
 * dtheta_d instead (the outside pair's moves with theta1 alone). */
static void torque_features(const float *dP, const float *dth, const struct friction *fr, int8_t d, float *x)
{
    for (uint8_t k = 0; k < MODEL_NT; k++) {
        uint8_t t = MODEL_TORQUE_TERM[k];
#if MODEL_HAS_FRICTION
        if (t >= 14) {
            uint8_t p = (uint8_t)(t - 14);
            x[k] = d < 0 ? fr->v[p] : p || d == 0 ? fr->slope[p] : 0.0f;
            continue;
        }
#else
        (void)fr;
#endif
        if (d < 0)
            x[k] = t < 4 ? dP[t] : t < 12 ? dP[(t - 4) >> 1] * dth[(t - 4) & 1] : dth[t - 12];
        else
            x[k] = t < 4 ? 0.0f : t < 12 ? (((t - 4) & 1) == d ? dP[(t - 4) >> 1] : 0.0f) : (t - 12 == d ? 1.0f : 0.0f);
    }
}

static void torques(const float *x, float *tau)
{
    tau[0] = tau[1] = 0.0f;
    for (uint8_t k = 0; k < MODEL_NT; k++) {
        tau[0] += x[k] * MODEL_TORQUE_COEF[k][0];
        tau[1] += x[k] * MODEL_TORQUE_COEF[k][1];
    }
}

/* 2 x 2 products: C = A B, A^T B (ta), A B^T (tb); y = A x. */
static void mul2(const float A[2][2], const float B[2][2], float C[2][2], uint8_t ta, uint8_t tb)
{
    for (uint8_t i = 0; i < 2; i++)
        for (uint8_t l = 0; l < 2; l++) {
            float s = 0.0f;
            for (uint8_t m = 0; m < 2; m++)
                s += (ta ? A[m][i] : A[i][m]) * (tb ? B[l][m] : B[m][l]);
            C[i][l] = s;
        }
}

static void apply2(const float A[2][2], const float *x, float *y)
{
    y[0] = A[0][0] * x[0] + A[0][1] * x[1];
    y[1] = A[1][0] * x[0] + A[1][1] * x[1];
}

/* What the forces were computed from, for their derivatives: features, (X^T X)^-1 x, torques,
 * J, P J, A^-1, K. */
struct force_parts {
    float x[MODEL_NT], Mx[MODEL_NT], tau[2], J[2][2], PJ[2][2], Ai[2][2], K[2][2];
};

/* Forces and their covariance from the torque error alone, at deflection dth (t: the trig of th0 + dth). */
static void forces(const float *dP, const struct trig *t, const float *dth, const struct friction *fr, float *F,
                   float C[2][2], struct force_parts *fp)
{
    torque_features(dP, dth, fr, -1, fp->x);
    torques(fp->x, fp->tau);
    float g = 1.0f, A[2][2], M[2][2];
    for (uint8_t i = 0; i < MODEL_NT; i++) { /* (X^T X)^-1 x, kept for the gradient's dg */
        float r = 0.0f;
        for (uint8_t j = 0; j < MODEL_NT; j++)
            r += MODEL_TORQUE_XTX[i][j] * fp->x[j];
        fp->Mx[i] = r;
        g += fp->x[i] * r;
    }
    jacobian(t, fp->J);
#if MODEL_HAS_PRIOR
    float p[2] = {MODEL_PRIOR_SD[0] * MODEL_PRIOR_SD[0], MODEL_PRIOR_SD[1] * MODEL_PRIOR_SD[1]};
    for (uint8_t i = 0; i < 2; i++)
        for (uint8_t l = 0; l < 2; l++)
            fp->PJ[i][l] = p[i] * fp->J[i][l];
    mul2(fp->J, fp->PJ, A, 1, 0); /* A = J^T P J + g R */
    for (uint8_t i = 0; i < 2; i++)
        for (uint8_t l = 0; l < 2; l++)
            A[i][l] += g * MODEL_TORQUE_RESID[i][l];
    inv2(A, fp->Ai);
    mul2(fp->PJ, fp->Ai, fp->K, 0, 0); /* K = P J A^-1 */
    apply2(fp->K, fp->tau, F);
    /* C = (P^-1 + J (g R)^-1 J^T)^-1, the information form of P - K J^T P: where the torques pin
     * a force down (C a few hundredths of P), that difference keeps only a digit or two in 32-bit
     * floats (the friction model's sample rows: Fx's standard error 5 % off). */
    for (uint8_t i = 0; i < 2; i++)
        for (uint8_t l = 0; l < 2; l++)
            A[i][l] = g * MODEL_TORQUE_RESID[i][l];
    inv2(A, M);
    mul2(fp->J, M, A, 0, 0);
    mul2(A, fp->J, M, 0, 1);
    M[0][0] += 1.0f / p[0];
    M[1][1] += 1.0f / p[1];
    inv2(M, C);
#else
    float JJ[2][2], S[2][2], AS[2][2];
    mul2(fp->J, fp->J, JJ, 0, 1); /* pinv(J^T) = (J J^T)^+ J for a 2 x 2 */
    inv2(JJ, M);
    mul2(M, fp->J, A, 0, 0);
    apply2(A, fp->tau, F);
    for (uint8_t i = 0; i < 2; i++)
        for (uint8_t l = 0; l < 2; l++)
            S[i][l] = g * MODEL_TORQUE_RESID[i][l];
    mul2(A, S, AS, 0, 0); /* C = A S A^T */
    mul2(AS, A, C, 0, 1);
#endif
}

#if MODEL_HAS_PRIOR
/* dF / d(dtheta), column d: the derivative of K tau with K = P J A^-1 and A = J^T P J + g R:
 * dK = (P dJ - K dA) A^-1, dA = dJ^T P J + (P J)^T dJ + dg R, dg = 2 x^T (X^T X)^-1 dx.
 * The host takes the same by central differences (PostureModel._force_covariance). */
static void force_gradient(const float *dP, const struct trig *t, const float *dth, const struct friction *fr,
                           const struct force_parts *fp, float G[2][2])
{
    float p[2] = {MODEL_PRIOR_SD[0] * MODEL_PRIOR_SD[0], MODEL_PRIOR_SD[1] * MODEL_PRIOR_SD[1]};
    float h2 = MODEL_H2, h3 = MODEL_H3;
    for (int8_t d = 0; d < 2; d++) {
        float dx[MODEL_NT], dtau[2], dg = 0.0f, dJ[2][2], dA[2][2], B[2][2], M[2][2], dK[2][2], y[2], z[2];
        torque_features(dP, dth, fr, d, dx);
        torques(dx, dtau);
        for (uint8_t i = 0; i < MODEL_NT; i++)
            if (dx[i] != 0.0f)
                dg += fp->Mx[i] * dx[i];
        dJ[0][0] = (d ? 0.0f : h2 * t->s1) + h3 * t->s12; /* theta1 moves both angles, theta2 the upper */
        dJ[0][1] = h3 * t->s12;
        dJ[1][0] = -(d ? 0.0f : h2 * t->c1) - h3 * t->c12;
        dJ[1][1] = -h3 * t->c12;
        mul2(dJ, fp->PJ, dA, 1, 0);
        mul2(fp->PJ, dJ, B, 1, 0);
        for (uint8_t i = 0; i < 2; i++)
            for (uint8_t l = 0; l < 2; l++)
                dA[i][l] += B[i][l] + 2.0f * dg * MODEL_TORQUE_RESID[i][l];
        mul2(fp->K, dA, B, 0, 0);
        for (uint8_t i = 0; i < 2; i++)
            for (uint8_t l = 0; l < 2; l++)
                M[i][l] = p[i] * dJ[i][l] - B[i][l];
        mul2(M, fp->Ai, dK, 0, 0);
        apply2(dK, fp->tau, y);
        apply2(fp->K, dtau, z);
        G[0][d] = y[0] + z[0];
        G[1][d] = y[1] + z[1];
    }
}
#else
#define DTH_STEP 1e-4f
#define SIN_STEP 9.99999998e-5f /* sin(DTH_STEP); its cosine is 1 to the float's precision */

/* The trig of the angles a step away: theta1 (and so theta1 + theta2) moved when k = 0, theta2 when k = 1. */
static void stepped(const struct trig *t, uint8_t k, float sign, struct trig *out)
{
    float sd = sign * SIN_STEP;
    out->c12 = t->c12 - t->s12 * sd;
    out->s12 = t->s12 + t->c12 * sd;
    out->c1 = k ? t->c1 : t->c1 - t->s1 * sd;
    out->s1 = k ? t->s1 : t->s1 + t->c1 * sd;
}

/* dF / d(dtheta) by central differences, as the host (a step of 1e-4 rad: the float's 7 digits
 * would drown the host's 1e-6), for a model without a force prior (files of earlier fits). */
static void force_gradient_numeric(const float *dP, const struct trig *t, const float *dth, const float *moved,
                                   float G[2][2])
{
    for (uint8_t k = 0; k < 2; k++) {
        float up[2] = {dth[0], dth[1]}, dn[2] = {dth[0], dth[1]}, Fu[2], Fd[2], Cx[2][2];
        struct trig tu, td;
        struct force_parts fp;
        struct friction fu, fd;
        up[k] += DTH_STEP;
        dn[k] -= DTH_STEP;
        stepped(t, k, 1.0f, &tu);
        stepped(t, k, -1.0f, &td);
#if MODEL_HAS_FRICTION
        friction_of(up, moved, &fu);
        friction_of(dn, moved, &fd);
#else
        (void)moved;
#endif
        forces(dP, &tu, up, &fu, Fu, Cx, &fp);
        forces(dP, &td, dn, &fd, Fd, Cx, &fp);
        G[0][k] = (Fu[0] - Fd[0]) / (2.0f * DTH_STEP);
        G[1][k] = (Fu[1] - Fd[1]) / (2.0f * DTH_STEP);
    }
}
#endif

static void posture(const float *P0, const float *P, const float *th0, const float *moved, const float *u,
                    struct model_out *out)
{
    float xa[MODEL_NA], dth[2] = {0.0f, 0.0f};
    angle_features(MODEL_ANGLE_TERM, MODEL_NA, u, xa);
    for (uint8_t k = 0; k < MODEL_NA; k++) {
        dth[0] += xa[k] * MODEL_ANGLE_COEF[k][0];
        dth[1] += xa[k] * MODEL_ANGLE_COEF[k][1];
    }
    float ga = 1.0f + quad(&MODEL_ANGLE_XTX[0][0], xa, MODEL_NA), cov_a[2][2];
    for (uint8_t i = 0; i < 2; i++)
        for (uint8_t j = 0; j < 2; j++)
            cov_a[i][j] = ga * MODEL_ANGLE_RESID[i][j];
    out->v[0] = dth[0];
    out->se[0] = sqrtf(cov_a[0][0]);
#if MODEL_N1
    float x1[MODEL_N1], t1 = 0.0f;
    angle_features(MODEL_THETA1_TERM, MODEL_N1, u, x1);
    for (uint8_t k = 0; k < MODEL_N1; k++)
        t1 += x1[k] * MODEL_THETA1_COEF[k];
    out->v[0] = t1;
    out->se[0] = sqrtf(MODEL_THETA1_VAR * (1.0f + quad(&MODEL_THETA1_XTX[0][0], x1, MODEL_N1)));
#endif
    out->v[1] = dth[1];
    out->se[1] = sqrtf(cov_a[1][1]);
    out->dth[0] = dth[0];
    out->dth[1] = dth[1];
    float dP[4], F[2], C[2][2], G[2][2];
    for (uint8_t k = 0; k < 4; k++)
        dP[k] = P0[k] - P[k];
    struct trig t;
    struct force_parts fp;
    struct friction fr; /* read only by a model with the friction terms */
#if MODEL_HAS_FRICTION
    friction_of(dth, moved, &fr);
#elif MODEL_HAS_PRIOR
    (void)moved;
#endif
    trig_of(th0[0] + dth[0], th0[1] + dth[1], &t);
    forces(dP, &t, dth, &fr, F, C, &fp);
#if MODEL_HAS_PRIOR
    force_gradient(dP, &t, dth, &fr, &fp, G);
#else
    force_gradient_numeric(dP, &t, dth, moved, G);
#endif
    for (uint8_t i = 0; i < 2; i++) {
        float c = C[i][i];
        for (uint8_t j = 0; j < 2; j++)
            c += G[i][j] * (cov_a[j][0] * G[i][0] + cov_a[j][1] * G[i][1]);
#if !MODEL_HAS_PRIOR
        if (fabsf(t.s12 * t.c1 - t.c12 * t.s1) < 1e-9f) /* sin(theta2) */
            c = INFINITY; /* a straight arm: without a prior the force along it is not determined */
#endif
        out->v[2 + i] = F[i];
        out->se[2 + i] = sqrtf(c > 0.0f ? c : 0.0f);
    }
}

#endif /* MODEL_HAS_POSTURE */

#if MODEL_HAS_PAPER

/* Where Eqs. 36-37 are evaluated: (J^-1)^T (1/m), cos(theta1), cos(theta2), sin(theta2). */
struct paper_posture {
    float js[2][2], c1, c2, s2, dc; /* dc = cos(theta1) - cos(theta2) */
};

/* At the angles whose sines are sn (|sn| <= 1, the angles within +-90 deg, so their cosines are
 * the positive roots): no trig function at all.  det J = h2 h3 sin(theta2) in closed form
 * (exactly 0 on a straight arm, as the host's). */
static void paper_posture_of(const float *sn, struct paper_posture *pp)
{
    struct trig t;
    float J[2][2], c2 = sqrtf(1.0f - sn[1] * sn[1]);
    t.c1 = sqrtf(1.0f - sn[0] * sn[0]);
    t.s1 = sn[0];
    t.c12 = t.c1 * c2 - t.s1 * sn[1];
    t.s12 = t.s1 * c2 + t.c1 * sn[1];
    jacobian(&t, J);
    pp->c1 = t.c1;
    pp->c2 = c2;
    pp->s2 = sn[1];
    /* c1 - c2 from the sines: near a straight rest both cosines are 1 - tiny, and their difference,
     * which Eq. 36's largest coefficient multiplies, would keep only a digit or two.
     * Both angles clipped at +-90 deg leave both cosines 0: their difference is 0, not 0/0. */
    float csum = t.c1 + c2;
    pp->dc = csum > 0.0f ? (sn[1] * sn[1] - sn[0] * sn[0]) / csum : 0.0f;
    float inv = 1.0f / (MODEL_H2 * MODEL_H3 * sn[1]);
    pp->js[0][0] = J[1][1] * inv;
    pp->js[0][1] = -J[1][0] * inv;
    pp->js[1][0] = -J[0][1] * inv;
    pp->js[1][1] = J[0][0] * inv;
}

/* Eq. 36 (row 0) or 37 (row 1)'s design. */
static void force_design(const float *dP, const struct paper_posture *pp, uint8_t row, float *x)
{
    float c1 = pp->c1, c2 = pp->c2, ja = pp->js[row][0], jb = pp->js[row][1];
    x[0] = ja * c1 * dP[0];
    x[1] = ja * c1 * dP[1];
    x[2] = ja * pp->dc * dP[2];
    x[3] = ja * pp->dc * dP[3];
    x[4] = jb * c2 * dP[2];
    x[5] = jb * c2 * dP[3];
}

static float dot(const __flash float *b, const float *x, uint8_t n)
{
    float s = 0.0f;
    for (uint8_t k = 0; k < n; k++)
        s += b[k] * x[k];
    return s;
}

/* Per-component force amplification ||row_k (J^-1)^T|| ||J|| (inf on a straight arm). */
static void amplification(const struct paper_posture *pp, float *amp)
{
    float h2 = MODEL_H2, h3 = MODEL_H3;
    float frob2 = h2 * h2 + 2.0f * h3 * h3 + 2.0f * h2 * h3 * pp->c2;
    float det = fabsf(h2 * h3 * pp->s2);
    float disc = frob2 * frob2 - 4.0f * det * det;
    float smax = sqrtf(0.5f * (frob2 + sqrtf(disc > 0.0f ? disc : 0.0f)));
    for (uint8_t k = 0; k < 2; k++)
        amp[k] = det > 0.0f ? sqrtf(pp->js[k][0] * pp->js[k][0] + pp->js[k][1] * pp->js[k][1]) * smax : INFINITY;
}

/* The paper's Eqs. 34-37: values, standard errors (with the held-out variances), ok per quantity. */
static void paper(const float *P0, const float *P, const float *u, float *v, float *se, uint8_t *ok, uint16_t *flags)
{
    float s[2] = {dot(MODEL_PAPER_B_THETA1, u, 2), dot(MODEL_PAPER_B_THETA2, u, 4)}, th[2];
    for (uint8_t k = 0; k < 2; k++) {
        uint8_t clipped = fabsf(s[k]) > 1.0f;
        if (clipped)
            s[k] = s[k] > 0.0f ? 1.0f : -1.0f;
        th[k] = asinf(s[k]);
        v[k] = th[k];
        ok[k] = !clipped;
        if (clipped)
            *flags |= k ? MODEL_FLAG_THETA2_CLIPPED : MODEL_FLAG_THETA1_CLIPPED;
    }
    float amp[2], dP[4], x[2][6];
    struct paper_posture pp;
    paper_posture_of(s, &pp);
    amplification(&pp, amp);
    for (uint8_t k = 0; k < 4; k++)
        dP[k] = P0[k] - P[k];
    for (uint8_t r = 0; r < 2; r++) {
        force_design(dP, &pp, r, x[r]);
        v[2 + r] = dot(r ? MODEL_PAPER_B_FY : MODEL_PAPER_B_FX, x[r], 6);
        uint8_t singular = !(amp[r] <= MODEL_MAX_AMPLIFICATION);
        ok[2 + r] = ok[0] && ok[1] && !singular;
        if (singular && ok[0] && ok[1])
            *flags |= MODEL_FLAG_SINGULAR;
    }
    if (!isfinite(v[2]) || !isfinite(v[3])) { /* theta2 = 0 exactly: the stand-in at the threshold */
        float t2[2] = {s[0], sinf(th[1] < 0.0f ? -MODEL_THETA2_THRESHOLD : MODEL_THETA2_THRESHOLD)}, xs[6];
        paper_posture_of(t2, &pp);
        for (uint8_t r = 0; r < 2; r++) {
            force_design(dP, &pp, r, xs);
            if (!isfinite(v[2 + r]))
                v[2 + r] = dot(r ? MODEL_PAPER_B_FY : MODEL_PAPER_B_FX, xs, 6);
        }
    }
#if MODEL_HAS_POSTURE
    /* Standard errors: held-out variance plus the coefficients' share (routes.paper_standard_errors);
     * a model of the paper's form alone carries no held-out variances, and has none. */
    float c[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    for (uint8_t q = 0; q < 2; q++) /* only the quantities that take the paper's form */
        if (MODEL_ROUTE[q] != ROUTE_POSTURE)
            c[q] = quad(q ? &MODEL_PAPER_COV_THETA2[0][0] : &MODEL_PAPER_COV_THETA1[0][0], u, q ? 4 : 2)
                / fmaxf(1.0f - s[q] * s[q], 1e-12f); /* cos^2 of the angle */
    for (uint8_t r = 0; r < 2; r++) {
        if (MODEL_ROUTE[2 + r] == ROUTE_POSTURE)
            continue;
        for (uint8_t k = 0; k < 6; k++)
            if (!isfinite(x[r][k]))
                x[r][k] = isnan(x[r][k]) ? 0.0f : copysignf(1e30f, x[r][k]);
        c[2 + r] = quad(r ? &MODEL_PAPER_COV_FY[0][0] : &MODEL_PAPER_COV_FX[0][0], x[r], 6);
    }
    for (uint8_t q = 0; q < 4; q++)
        se[q] = sqrtf(MODEL_PAPER_VAR[q] + (isfinite(c[q]) ? fmaxf(c[q], 0.0f) : INFINITY));
#else
    for (uint8_t q = 0; q < 4; q++)
        se[q] = 0.0f;
#endif
}

#endif /* MODEL_HAS_PAPER */

void model_predict(const float *P0_in, const float *P_in, const float *th0, const float *moved, struct model_out *out)
{
    float P0[4], P[4], u[4];
    uint8_t bad = 0;
    for (uint8_t k = 0; k < 4; k++)
        bad |= !(P0_in[k] > 0.0f && P_in[k] > 0.0f && isfinite(P0_in[k]) && isfinite(P_in[k]));
    for (uint8_t k = 0; k < 4; k++) {
        P0[k] = bad ? 1.0f : P0_in[k];
        P[k] = bad ? 1.0f : P_in[k];
        u[k] = P0[k] / P[k] - 1.0f;
    }
    out->flags = bad ? MODEL_FLAG_BAD_PRESSURE : 0;
    out->dth[0] = out->dth[1] = 0.0f;
    float wpo[4] = {1.0f, 1.0f, 1.0f, 1.0f}; /* the posture form's weight in each estimate */
#if MODEL_HAS_POSTURE
    posture(P0, P, th0, moved, u, out);
#else
    (void)th0;
    (void)moved;
#endif
#if MODEL_HAS_PAPER
    float vp[4], sp[4];
    uint8_t okp[4];
    uint16_t pflags = 0;
    paper(P0, P, u, vp, sp, okp, &pflags);
    for (uint8_t q = 0; q < 4; q++) {
        uint8_t route = MODEL_ROUTE[q];
#if MODEL_HAS_POSTURE
        if (route == ROUTE_BLEND) {
            /* Stacked: w x_posture + (1 - w) x_paper; where the paper's form has none, the posture's alone. */
            float w = MODEL_BLEND_W[q], rho = MODEL_BLEND_RHO[q], so = out->se[q];
            float v = w * out->v[q] + (1.0f - w) * vp[q];
            float var = w * w * so * so + (1.0f - w) * (1.0f - w) * sp[q] * sp[q] + 2.0f * w * (1.0f - w) * rho * so * sp[q];
            float s = sqrtf(var > 0.0f ? var : 0.0f);
            if (okp[q] && isfinite(v) && isfinite(s)) {
                out->v[q] = v;
                out->se[q] = s;
                wpo[q] = w;
            }
            continue;
        }
#endif
        if (route == ROUTE_PAPER) {
            out->v[q] = vp[q];
            out->se[q] = MODEL_HAS_POSTURE ? sp[q] : 0.0f; /* a file of the paper's form alone has none */
            wpo[q] = 0.0f;
            uint16_t why = q == 0 ? MODEL_FLAG_THETA1_CLIPPED : q == 1 ? MODEL_FLAG_THETA2_CLIPPED : MODEL_FLAG_SINGULAR;
            if (!okp[q] && !bad)
                out->flags |= pflags & why;
        }
    }
#endif
    for (uint8_t q = 0; q < 4; q++)
        if (!bad && !(out->se[q] <= MODEL_LIMIT[q]))
            out->flags |= (uint16_t)(MODEL_FLAG_UNCERTAIN << q);
#if MODEL_HAS_POSTURE && MODEL_HAS_HELD_OUT
    /* The plan's direction term widens the intervals after the flags, in the posture form's weight. */
    for (uint8_t q = 0; q < 4; q++)
        if (MODEL_HELD_OUT_VAR[q] > 0.0f)
            out->se[q] = sqrtf(out->se[q] * out->se[q] + wpo[q] * wpo[q] * MODEL_HELD_OUT_VAR[q]);
#else
    (void)wpo;
#endif
}
