/*
 * The rig wire protocol, version 1.1, device side: everything that needs no hardware.
 *
 * Frame, event and estimate line formatting, the XOR checksum, the command line assembler
 * and parser (valves, pressure limit and model commands included), the pressure-limit check,
 * and the arithmetic from a commanded RATE to timer and ADC settings.  Compiled for
 * the board and for the host alike (plain C99, <stdint.h> only), so the host
 * tests (firmware/test/) check exactly the code the board runs.
 */
#ifndef LABCLI_PROTO_H
#define LABCLI_PROTO_H

#include <stdint.h>

#include "config.h"

/* "$D," + 10 + "," + 10 + N x ",65535" + "*HH\n" + NUL, with room to spare. */
#define PROTO_FRAME_MAX (3 + 10 + 1 + 10 + N_CHANNELS * 6 + 4 + 1)
#define PROTO_REPLY_MAX 160 /* the longest: the stop log with every counter at 2^32 - 1 */

/* XOR of the bytes strictly between '$' and '*'. */
uint8_t proto_checksum(const char *payload, uint8_t len);

/* Decimal digits of x at p (no NUL); returns the end. */
char *proto_put_u32(char *p, uint32_t x);

/* One data line "$D,<seq>,<t_us>,<v1>,...,<vn>*HH\n" into out (>= PROTO_FRAME_MAX); returns its length. */
uint8_t proto_format_frame(char *out, uint32_t seq, uint32_t t_us, const uint16_t *values, uint8_t n);

/* Protocol counts (0..4095 per 0..Vref) from the sum of OVERSAMPLE 10-bit conversions. */
uint16_t proto_counts(uint16_t sum);

/* ---- command lines ---- */

struct proto_line {
    char buf[CMD_MAX];
    uint8_t len;
    uint8_t overlong;
};

enum { LINE_PENDING = 0, LINE_READY, LINE_OVERLONG };

/* Feed one received byte.  LINE_READY: buf holds the line (NUL-terminated, '\r' stripped);
 * LINE_OVERLONG: a line longer than CMD_MAX - 1 bytes ended and was thrown away.
 * Either way the next byte starts a new line. */
uint8_t proto_line_push(struct proto_line *line, char c);

/* ---- timing ---- */

struct proto_rate {
    uint32_t mhz;      /* the rate actually set, millihertz (rounded) */
    uint32_t ticks;    /* frame period in timer ticks (TICK_HZ) */
    uint16_t n_sub;    /* the period as n_sub compare periods of base or base + 1 ticks */
    uint16_t base;
    uint16_t extra;    /* how many of them are base + 1 */
    uint8_t adc_ps_log2; /* ADC clock = F_CPU >> adc_ps_log2 (ADPS bits) */
    uint8_t idle_every;  /* not streaming, one period in idle_every is sampled (the limit's check) */
};

/* Timer and ADC settings for a requested rate (millihertz, > 0). */
void proto_rate_settings(uint32_t mhz, struct proto_rate *rate);

/* ---- commands ---- */

enum proto_action {
    PROTO_NONE = 0,
    PROTO_REPLY,
    PROTO_RATE,
    PROTO_START,
    PROTO_STOP,
    PROTO_VALVE,    /* st->valve_next holds the valves wanted; the reply is ready */
    PROTO_PMAX,     /* st->pmax changed (to store) */
    PROTO_BASELINE, /* the model is to retake its baseline */
};

#define VALVE_SUPPLY 'S'
#define VALVE_HOLD 'H'
#define VALVE_VENT 'V'

struct proto_state {
    struct proto_rate rate;
    uint8_t streaming;
    uint8_t valve[N_VALVES];      /* the valves as they are ('S', 'H', 'V'); the caller keeps it */
    uint8_t valve_next[N_VALVES]; /* what a VALVE command asks for */
    uint16_t pmax[N_VALVES];      /* the pressure limit, counts */
    uint8_t est_every;            /* an estimate line after every n-th data line (0: none) */
    const char *model;            /* the model's id (RAM), or 0 for a board without a model */
    const char *estimates;        /* its quantities, "theta1:theta2:Fx:Fy" (RAM) */
};

/* Rate at power-up, valves holding, the default limit, no model. */
void proto_init(struct proto_state *st);

/* Answer one command line (NUL-terminated, no '\n').  reply (>= PROTO_REPLY_MAX) gets the
 * reply line with its '\n', or "" for an empty line.  The action tells the caller what to
 * change: PROTO_RATE (st->rate is the new rate), PROTO_START, PROTO_STOP (st->streaming
 * already updated), PROTO_REPLY (just send the reply), PROTO_NONE (nothing to send). */
uint8_t proto_command(struct proto_state *st, const char *line, char *reply);

/* The reply to a line longer than CMD_MAX - 1 bytes. */
void proto_overlong_reply(char *reply);

/* Log lines: the banner at power-up, the stream's settings at START, its statistics at STOP. */
void proto_banner(char *out);
void proto_start_log(char *out, const struct proto_state *st);
struct proto_stats {
    uint32_t sent;       /* frames queued for the UART */
    uint32_t uart_full;  /* frames dropped: the UART buffer had no room (baud too low for the rate) */
    uint32_t adc_late;   /* frames dropped: the previous frame's conversions still running */
    uint32_t unformatted; /* frames dropped: the main loop had not formatted the previous one */
    uint16_t sampling_us_max; /* longest time from a frame's tick to its last conversion */
};
void proto_stop_log(char *out, const struct proto_stats *stats);

/* ---- wire protocol 1.1: events, estimates, the limit ---- */

/* Longest event line: "$E," n "," t_us ",BASELINE,release," frames then N_CHANNELS x ",4294967295" "*HH\n". */
#define PROTO_EVENT_MAX (3 + 10 + 1 + 10 + 18 + 5 + N_CHANNELS * 11 + 4 + 1)
#define PROTO_ESTIMATE_MAX (3 + 10 + 1 + 10 + 4 * 13 + 6 + 4 + 1)

/* Event lines (the event number n, the board's clock t_us); each returns the line's length. */
uint8_t proto_event_valve(char *out, uint32_t n, uint32_t t_us, const uint8_t *states, const char *cause_pstr);
uint8_t proto_event_pmax(char *out, uint32_t n, uint32_t t_us, uint8_t valve, uint16_t counts);
uint8_t proto_event_reset(char *out, uint32_t n, uint32_t t_us, const char *cause_pstr);
/* A baseline of count frames: count, then every channel's sum of counts. */
uint8_t proto_event_baseline(char *out, uint32_t n, uint32_t t_us, const char *cause_pstr, const uint32_t *sum,
                             uint16_t count);

/* An estimate line: values[k] / 10^decimals[k], then the flags. */
uint8_t proto_format_estimate(char *out, uint32_t seq, uint32_t t_us, const int32_t *values, const uint8_t *decimals,
                              uint8_t n, uint16_t flags);

/* Which valves (bit k: valve k) read above their limit and are not venting. */
uint8_t proto_over_limit(const struct proto_state *st, const uint16_t *counts);

/* A string from flash (PSTR on the board) into out; returns the end. */
char *proto_put_pstr(char *out, const char *pstr);

/* The name of valve k (a pressure channel's) into out; returns the end. */
char *proto_put_valve_name(char *out, uint8_t valve);

#endif
