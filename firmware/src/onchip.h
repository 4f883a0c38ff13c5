/*
 * Estimates on the chip (a firmware built with MODEL=model.h): the model's baseline, a load and
 * release detector, and the estimate lines.  See onchip.c.
 */
#ifndef LABCLI_ONCHIP_H
#define LABCLI_ONCHIP_H

#include <stdint.h>

#include "proto.h"
#include "sampler.h"

/* At power-up: the model's id and quantities in st (CAPS), estimates off. */
void onchip_init(struct proto_state *st);

/* Every frame, streamed or not (cheap): the baseline's sums, the detector; the newest frame kept.
 * 1 when a baseline was just taken: its event line is then onchip_baseline_event's. */
uint8_t onchip_frame(const struct frame *f, const uint16_t *counts, const struct proto_state *st);
uint8_t onchip_baseline_event(char *out, uint32_t n, uint32_t t_us);

/* The model on the newest frame (long: milliseconds); its estimate line when one is due. */
void onchip_estimate(const struct proto_state *st);

/* BASELINE; the valves moved (the baseline no longer holds); a new rate; a new stream. */
void onchip_baseline(void);
void onchip_valves_changed(void);
void onchip_rate(const struct proto_rate *rate);
void onchip_start(void);

/* The estimates' statistics for the STOP log: "# estimates: ..." */
void onchip_stop_log(char *out);

#endif
