/*
 * The fitted force model on the chip (make MODEL=model.h, written by labcli export-model):
 * joint deflections and the tip force from the baseline and the present pressures, as
 * PostureModel.predict computes them pressure-only (labcli/papers/takuma2014/models/posture.py,
 * routes.py, takuma.py), in 32-bit floats.  Plain C: the host builds it too (test/model_tool.c).
 */
#ifndef LABCLI_MODEL_API_H
#define LABCLI_MODEL_API_H

#include <stdint.h>

/* Flags of an estimate line (labcli.core.boardlines.ESTIMATE_FLAGS). */
#define MODEL_FLAG_UNCERTAIN 1U /* << quantity: its standard error is over the model's limit */
#define MODEL_FLAG_BAD_PRESSURE 16U
#define MODEL_FLAG_THETA1_CLIPPED 32U
#define MODEL_FLAG_THETA2_CLIPPED 64U
#define MODEL_FLAG_SINGULAR 128U
#define MODEL_FLAG_NO_BASELINE 256U
#define MODEL_FLAG_LOADED 512U

struct model_out {
    float v[4];   /* theta1, theta2 (rad, deflections), Fx, Fy (N) */
    float se[4];  /* their standard errors (0 where the model has none) */
    float dth[2]; /* the posture form's own deflections (rad, routes aside): what the history reads */
    uint16_t flags;
};

/* P0, P: baseline and present pressures (MPa gauge) of L1, R1, L2, R2; th0: rest posture (rad);
 * moved: the joints' motion into the baseline from the previous load's posture (rad, 2), which a
 * model with the sleeves' friction terms reads (0: unknown, as for the first load). */
void model_predict(const float *P0, const float *P, const float *th0, const float *moved, struct model_out *out);

/* 1 when the model reads the history of loads (the friction terms), else 0. */
uint8_t model_uses_history(void);

/* erf(x) to within 5e-7 (Abramowitz & Stegun 7.1.26: 1.5e-7, and the float's rounding), and its
 * derivative in *slope: the friction terms' fade on a chip whose libc has no erf. */
float model_erf(float x, float *slope);

/* One channel's counts as MPa or rad (the model's calibration). */
float model_si(uint8_t channel, float counts);

/* Which channel is actuator k (L1, R1, L2, R2) and joint j (1, 2); the force limits; the lowest
 * pressure a baseline may have (counts of actuator k's channel). */
uint8_t model_p_channel(uint8_t k);
uint8_t model_pot_channel(uint8_t j);
float model_limit(uint8_t q);
float model_baseline_min_counts(uint8_t k);

/* The model's id and quantities, for CAPS; its channel names (must be the firmware's). */
extern const char model_id[];
extern const char model_quantities[];
extern const char model_channel_names[];

#endif
