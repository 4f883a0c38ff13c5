/*
 * Estimates on the chip: the model of model.c on the newest frame, against a baseline the chip
 * takes itself, and the estimate lines ($S) the host asks for with EST <n>.
 *
 * The baseline is the mean of BASELINE_US of frames (pressures and potentiometers), taken
 *   - when the host sends BASELINE;
 *   - after a release: a load was on (a force component the model can see, one not flagged
 *     uncertain, above LOAD_ON times its limit) and is off again (below LOAD_OFF times it) with
 *     the pressures steady, and they stay steady while the baseline is taken;
 *   - at the start: no baseline yet, the pressures steady and every chamber above the model's
 *     minimum (0.02 MPa).
 * Moving a valve forgets the baseline (the chambers' air is not the same): the start rule then
 * takes a new one once the pressures have settled.  Steady means two detector windows
 * (WINDOW_US each) in which no pressure's running mean moved by more than STEADY_COUNTS.
 * Until a baseline exists estimates carry the no-baseline flag and zeros.  The chip does not
 * follow a leak's slow drift by itself: the host retakes the baseline (BASELINE) when it wants.
 *
 * A model with the sleeves' friction terms reads the history of loads, as labcli sense keeps it:
 * while a load is on (its force still above LOAD_OFF limits) and the pressures are steady, the
 * chip keeps the posture it holds the arm in (the rest plus the model's own deflections); each
 * baseline taken after that gets the motion into it (its rest less that posture), and the
 * estimates of the next load read it.  Estimates of the idle rig read none.
 *
 * The model takes milliseconds; frames that arrive meanwhile wait in the sampler's queue, are
 * sent and checked against the limit, and the next estimate is of the newest of them: estimates
 * thin out, data lines do not (the STOP log counts the frames skipped).
 */
#include <string.h>

#include "model.h"
#include "onchip.h"
#include "uart.h"

#ifdef __AVR__
#include <avr/pgmspace.h>
#else
#define PSTR(s) (s)
#endif

#define BASELINE_US 500000UL
#define WINDOW_US 250000UL
#define STEADY_COUNTS 3
#define LOAD_ON 2.0f
#define LOAD_OFF 1.0f
#define EMA_SHIFT 3 /* running mean over about 8 frames, in 1/16 counts */

enum { CAUSE_HOST = 1, CAUSE_RELEASE, CAUSE_START };

static struct {
    uint8_t have_base, taking, cause, loaded, steady_windows, window_open, still;
    float P0[4], th0[2];
    uint8_t have_before, have_moved;
    float before[2], moved[2]; /* the last load's posture; the motion into the present baseline (rad) */
    uint32_t sum[N_CHANNELS], first_us, window_us;
    uint16_t n_sum;
    int32_t mean[4], lo[4], hi[4]; /* 1/16 counts */
    struct frame newest;
    uint16_t counts[N_CHANNELS];
    uint8_t pending, sent_any;
    uint16_t seen;
    uint32_t last_sent, made, skipped, ticks_sum, ticks_max, full;
} e;

static const uint8_t DECIMALS[4] = {6, 6, 4, 4}; /* rad to the microradian, N to 0.1 mN */

void onchip_init(struct proto_state *st)
{
    memset(&e, 0, sizeof e);
    /* A model written for other channels would read the wrong inputs: the board offers none then. */
    if (!strcmp(model_channel_names, CHANNEL_NAMES)) {
        st->model = model_id;
        st->estimates = model_quantities;
    }
}

static void start_baseline(uint8_t cause)
{
    memset(e.sum, 0, sizeof e.sum);
    e.n_sum = 0;
    e.taking = 1;
    e.cause = cause;
}

void onchip_baseline(void)
{
    start_baseline(CAUSE_HOST);
}

void onchip_valves_changed(void)
{
    e.have_base = 0;
    e.taking = 0;
    e.loaded = 0;
    e.steady_windows = 0;
}

void onchip_rate(const struct proto_rate *rate)
{
    (void)rate; /* the detector counts time, not frames */
    e.window_open = 0;
}

void onchip_start(void)
{
    e.made = e.skipped = e.ticks_sum = e.ticks_max = e.full = 0;
    e.seen = 0;
    e.pending = 0; /* a frame of before the stream is not this stream's to estimate */
    e.sent_any = 0;
}

/* Two whole windows without movement, and none in the window under way. */
static uint8_t steady(void)
{
    return e.steady_windows >= 2 && e.still;
}

/* The running means of the pressures and the windows that judge them steady. */
static void detector(const uint16_t *counts, uint32_t t_us)
{
    for (uint8_t k = 0; k < 4; k++) {
        int32_t x = (int32_t)counts[model_p_channel(k)] << 4;
        e.mean[k] = e.window_open || e.steady_windows ? e.mean[k] + ((x - e.mean[k]) >> EMA_SHIFT) : x;
    }
    if (!e.window_open) {
        e.window_open = 1;
        e.still = 1;
        e.window_us = t_us;
        memcpy(e.lo, e.mean, sizeof e.lo);
        memcpy(e.hi, e.mean, sizeof e.hi);
        return;
    }
    uint8_t still = 1;
    for (uint8_t k = 0; k < 4; k++) {
        if (e.mean[k] < e.lo[k])
            e.lo[k] = e.mean[k];
        if (e.mean[k] > e.hi[k])
            e.hi[k] = e.mean[k];
        still &= e.hi[k] - e.lo[k] <= STEADY_COUNTS * 16;
    }
    e.still = still;
    if (!still)
        e.steady_windows = 0; /* a load's first frames end the steadiness at once, not at the window's end */
    if (t_us - e.window_us >= WINDOW_US) {
        e.steady_windows = still ? (uint8_t)(e.steady_windows < 255 ? e.steady_windows + 1 : 255) : 0;
        e.window_open = 0;
    }
}

/* Add a frame to the baseline being taken; 1 once it is complete. */
static uint8_t take(const uint16_t *counts, uint32_t t_us)
{
    if (!e.n_sum)
        e.first_us = t_us;
    for (uint8_t i = 0; i < N_CHANNELS; i++)
        e.sum[i] += counts[i];
    e.n_sum++;
    if (t_us - e.first_us < BASELINE_US)
        return 0;
    for (uint8_t k = 0; k < 4; k++) {
        uint8_t ch = model_p_channel(k);
        e.P0[k] = model_si(ch, (float)e.sum[ch] / (float)e.n_sum);
    }
    for (uint8_t j = 0; j < 2; j++) {
        uint8_t ch = model_pot_channel(j);
        e.th0[j] = model_si(ch, (float)e.sum[ch] / (float)e.n_sum);
    }
    if (e.have_before) {
        e.moved[0] = e.th0[0] - e.before[0];
        e.moved[1] = e.th0[1] - e.before[1];
        e.have_moved = 1;
    }
    e.taking = 0;
    e.have_base = 1;
    e.loaded = 0;
    return 1;
}

uint8_t onchip_frame(const struct frame *f, const uint16_t *counts, const struct proto_state *st)
{
    (void)st;
    detector(counts, f->t_us);
    if (e.taking && e.cause != CAUSE_HOST && !e.still) {
        /* The pressures moved while the chip took a baseline of its own: not released after all. */
        e.taking = 0;
        e.loaded = e.cause == CAUSE_RELEASE;
    }
    uint8_t taken = e.taking && take(counts, f->t_us);
    if (!e.have_base && !e.taking && steady()) {
        uint8_t aired = 1;
        for (uint8_t k = 0; k < 4; k++)
            aired &= (float)counts[model_p_channel(k)] > model_baseline_min_counts(k);
        if (aired)
            start_baseline(CAUSE_START);
    }
    e.newest = *f;
    memcpy(e.counts, counts, sizeof e.counts);
    e.pending = 1;
    e.seen += f->streamed; /* the stream's frames: those an estimate may skip */
    return taken;
}

uint8_t onchip_baseline_event(char *out, uint32_t n, uint32_t t_us)
{
    const char *cause = e.cause == CAUSE_HOST ? PSTR("host") : e.cause == CAUSE_RELEASE ? PSTR("release") : PSTR("start");
    return proto_event_baseline(out, n, t_us, cause, e.sum, e.n_sum);
}

static int32_t scaled(float v, uint8_t decimals)
{
    float s = 1.0f;
    for (uint8_t i = 0; i < decimals; i++)
        s *= 10.0f;
    float x = v * s;
    if (!(x > -2.0e9f && x < 2.0e9f))
        return x > 0.0f ? 2000000000L : -2000000000L; /* and the quantity is flagged uncertain */
    return (int32_t)(x + (x >= 0.0f ? 0.5f : -0.5f));
}

static void send_estimate(const struct model_out *out, const struct proto_state *st)
{
    const struct frame *f = &e.newest;
    if (!f->streamed || !st->est_every || (e.sent_any && f->seq - e.last_sent < st->est_every))
        return;
    int32_t v[4];
    for (uint8_t q = 0; q < 4; q++)
        v[q] = scaled(out->v[q], DECIMALS[q]);
    char line[PROTO_ESTIMATE_MAX];
    uint8_t n = proto_format_estimate(line, f->seq, f->t_us, v, DECIMALS, 4, out->flags);
    if (uart_tx_free() < n) {
        e.full++;
        return;
    }
    uart_write(line, n);
    e.last_sent = f->seq;
    e.sent_any = 1;
}

void onchip_estimate(const struct proto_state *st)
{
    if (!e.pending || !st->model)
        return;
    e.pending = 0;
    e.skipped += e.seen > 1 ? e.seen - 1U : 0U;
    e.seen = 0;
    struct model_out out;
    memset(&out, 0, sizeof out);
    if (e.have_base) {
        float P[4];
        for (uint8_t k = 0; k < 4; k++) {
            uint8_t ch = model_p_channel(k);
            P[k] = model_si(ch, (float)e.counts[ch]);
        }
        uint32_t t0 = sampler_ticks();
        model_predict(e.P0, P, e.th0, e.loaded && e.have_moved ? e.moved : 0, &out);
        uint32_t ticks = sampler_ticks() - t0;
        e.made++;
        e.ticks_sum += ticks;
        if (ticks > e.ticks_max)
            e.ticks_max = ticks;
        /* The load: the largest force component the model can see (not flagged uncertain), in limits. */
        float r = 0.0f;
        for (uint8_t q = 2; q < 4; q++) {
            if (out.flags & (MODEL_FLAG_UNCERTAIN << q))
                continue;
            float x = out.v[q] / model_limit(q);
            r = x > r ? x : -x > r ? -x : r;
        }
        if (e.loaded && r >= LOAD_OFF && steady() && model_uses_history()) {
            e.before[0] = e.th0[0] + out.dth[0]; /* the posture this load holds the arm in */
            e.before[1] = e.th0[1] + out.dth[1];
            e.have_before = 1;
        }
        if (!e.loaded && r > LOAD_ON)
            e.loaded = 1;
        else if (e.loaded && r < LOAD_OFF && steady() && !e.taking) {
            e.loaded = 0;
            start_baseline(CAUSE_RELEASE);
        }
    } else {
        out.flags = MODEL_FLAG_NO_BASELINE;
    }
    if (e.loaded)
        out.flags |= MODEL_FLAG_LOADED;
    for (uint8_t q = 0; q < 4; q++)
        if (!(out.v[q] > -1e9f && out.v[q] < 1e9f))
            out.flags |= (uint16_t)(MODEL_FLAG_UNCERTAIN << q);
    send_estimate(&out, st);
}

void onchip_stop_log(char *out)
{
    uint32_t per_us = (uint32_t)(TICK_HZ / 1000000UL);
    char *p = proto_put_pstr(out, PSTR("# estimates: "));
    p = proto_put_u32(p, e.made);
    p = proto_put_pstr(p, PSTR(" made, "));
    p = proto_put_u32(p, e.skipped);
    p = proto_put_pstr(p, PSTR(" frames skipped while busy, "));
    p = proto_put_u32(p, e.made ? e.ticks_sum / e.made / per_us : 0);
    p = proto_put_pstr(p, PSTR(" us mean, "));
    p = proto_put_u32(p, e.ticks_max / per_us);
    p = proto_put_pstr(p, PSTR(" us at most per estimate, "));
    p = proto_put_u32(p, e.full);
    p = proto_put_pstr(p, PSTR(" lines dropped (uart full)\n"));
    *p = '\0';
}
