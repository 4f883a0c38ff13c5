/*
 * Timer-paced sampling: Timer1 ticks at the commanded rate and keeps the device
 * clock (t_us); each tick starts N_CHANNELS x OVERSAMPLE ADC conversions, run
 * back to back by the ADC interrupt; finished frames wait for the main loop in a
 * short queue (FRAME_QUEUE).  Frames are sampled streaming or not: the pressure
 * limit is checked on every one; only those of a stream are numbered and sent.
 */
#ifndef LABCLI_SAMPLER_H
#define LABCLI_SAMPLER_H

#include <stdint.h>

#include "config.h"
#include "proto.h"

struct frame {
    uint32_t seq;   /* frame counter, +1 per tick while streaming, dropped frames included */
    uint32_t t_us;  /* device clock at the tick that started the conversions */
    uint16_t sum[N_CHANNELS]; /* sums of OVERSAMPLE 10-bit conversions per channel */
    uint8_t streamed; /* sampled for the stream (seq is its number), else only for the limit */
};

void sampler_init(const struct proto_rate *rate);

/* The new period starts at the end of the current one, so the device clock never jumps. */
void sampler_set_rate(const struct proto_rate *rate);

/* Start (counters reset) and stop streaming; stop keeps the frames being sampled or queued
 * for the limit check, but they are no longer sent. */
void sampler_start(void);
void sampler_stop(void);

/* Copy out the oldest finished frame, if any; 1 if there was one. */
uint8_t sampler_take(struct frame *out);

/* The device clock now, us (wrapping like t_us), and the free-running count of timer ticks. */
uint32_t sampler_now_us(void);
uint32_t sampler_ticks(void);

/* Frames dropped by the sampler since start (adc_late, unformatted) and the longest time from a
 * frame's tick to its hand-over. */
void sampler_stats(struct proto_stats *stats);

#endif
