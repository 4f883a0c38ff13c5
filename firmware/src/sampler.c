/*
 * Timer1 in CTC mode at F_CPU / 8 paces the frames and keeps the device clock;
 * the ADC interrupt runs each frame's conversions.  See sampler.h.
 *
 * Timing: a frame period of `ticks` timer ticks is n_sub compare periods of
 * base + 1 or base + 2 ticks (proto_rate_settings), so any period from 1 s down
 * is exact to one tick (0.5 us at 16 MHz), and the device clock adds up the
 * ticks that actually elapsed: it stays exact across RATE changes and wraps
 * at 2^32 us like the protocol's t_us.
 *
 * A frame's conversions go into `sampling`; the main loop copies it out
 * (sampler_take) before the next tick may reuse it, else that next frame is
 * dropped ("unformatted").
 *
 * Single-conversion mode, one conversion started by the previous one's
 * interrupt: the channel is chosen before each start, so no conversion has to
 * be thrown away after switching channels (in free-running mode the one already
 * under way would still be of the old channel).
 */
#include <avr/interrupt.h>
#include <avr/io.h>

#include "events.h"
#include "sampler.h"

#if TIMER_PRESCALE != 8
#error "sampler.c sets Timer1's clock select for a prescaler of 8"
#endif
#if TICK_HZ % 1000000UL
#error "the device clock needs a whole number of timer ticks per microsecond"
#endif
#define TICKS_PER_US ((uint8_t)(TICK_HZ / 1000000UL))

#define ADMUX_BASE _BV(REFS0) /* reference: AVCC (the board's 5 V), result right adjusted */

/* Timer state: the timer interrupt's, except `pending` handed over with interrupts off. */
static struct proto_rate rate_now;
static struct proto_rate rate_next;
static volatile uint8_t rate_pending;
static uint16_t sub;            /* compare period within the frame period */
static uint32_t t_us = T_US_START;
static uint8_t t_ticks;         /* ticks not yet a whole microsecond */
static uint32_t ticks_total;    /* free-running tick count, for the sampling time */
static uint32_t seq = SEQ_START;
static volatile uint8_t streaming;

/* ADC state: the frame being sampled, then (frame_done) waiting for the main loop. */
static volatile uint8_t adc_busy;
static volatile uint8_t frame_done;
static uint8_t adc_ch, adc_n;
static uint16_t adc_acc;
static struct frame sampling;
static uint32_t sampling_tick;

static volatile uint32_t n_adc_late, n_unformatted;
static volatile uint16_t sampling_us_max;

static uint16_t compare_top(void)
{
    return (uint16_t)(rate_now.base + (sub < rate_now.extra ? 1 : 0));
}

void sampler_init(const struct proto_rate *rate)
{
    rate_now = *rate;
    sub = 0;
    DIDR0 = 0x3F; /* A0-A5 analog only: no digital input buffers switching on the signals */
    ADMUX = ADMUX_BASE;
    /* The first conversion after enabling takes 25 ADC clocks to set up the analog part: do it now. */
    ADCSRA = _BV(ADEN) | _BV(ADSC) | rate_now.adc_ps_log2;
    while (ADCSRA & _BV(ADSC))
        ;
    TCCR1A = 0;
    TCCR1B = _BV(WGM12); /* CTC on OCR1A, stopped while it is set up */
    OCR1A = compare_top();
    TCNT1 = 0;
    TIMSK1 = _BV(OCIE1A);
    TCCR1B = _BV(WGM12) | _BV(CS11); /* clock / 8 */
}

void sampler_set_rate(const struct proto_rate *rate)
{
    cli();
    rate_next = *rate;
    rate_pending = 1;
    sei();
}

void sampler_start(void)
{
    cli();
    n_adc_late = 0;
    n_unformatted = 0;
    sampling_us_max = 0;
    frame_done = 0;
    streaming = 1;
    sei();
}

void sampler_stop(void)
{
    cli();
    streaming = 0;
    if (adc_busy) {
        /* Let the conversion under way finish unheard; its frame is not sent. */
        ADCSRA &= (uint8_t)~_BV(ADIE);
        adc_busy = 0;
    }
    frame_done = 0;
    sei();
}

/* Timer ticks since the frame's tick (the timer interrupt may be pending). Interrupts off. */
static uint32_t ticks_since_tick(void)
{
    uint16_t tcnt = TCNT1;
    uint32_t now = ticks_total + tcnt;
    if ((TIFR1 & _BV(OCF1A)) && tcnt < OCR1A / 2)
        now += OCR1A + 1UL;
    return now - sampling_tick;
}

uint8_t sampler_take(struct frame *out)
{
    uint8_t got = 0;
    cli();
    if (frame_done) {
        *out = sampling;
        frame_done = 0;
        got = 1;
        /* From the tick to the hand-over: the conversions, plus however long the main loop took. */
        uint32_t us = ticks_since_tick() / TICKS_PER_US;
        if (us > sampling_us_max)
            sampling_us_max = us > 0xFFFF ? 0xFFFF : (uint16_t)us;
    }
    sei();
    return got;
}

void sampler_stats(struct proto_stats *stats)
{
    cli();
    stats->adc_late = n_adc_late;
    stats->unformatted = n_unformatted;
    stats->sampling_us_max = sampling_us_max;
    sei();
}

/* A frame period begins: its seq is used whatever becomes of the frame. */
static void frame_tick(void)
{
    if (!streaming)
        return;
    uint32_t s = seq++;
    if (adc_busy) {
        n_adc_late++; /* the previous frame's conversions are still running */
        return;
    }
    if (frame_done) {
        n_unformatted++; /* the main loop has not taken the previous frame yet */
        return;
    }
    sampling.seq = s;
    sampling.t_us = t_us;
    sampling_tick = ticks_total;
    adc_ch = 0;
    adc_n = 0;
    adc_acc = 0;
    adc_busy = 1;
    ADMUX = ADMUX_BASE;
    ADCSRA = _BV(ADEN) | _BV(ADSC) | _BV(ADIE) | _BV(ADIF) | rate_now.adc_ps_log2;
}

ISR(TIMER1_COMPA_vect)
{
    uint16_t ticks = OCR1A + 1; /* the compare period that just ended */
    ticks_total += ticks;
    uint16_t acc = (uint16_t)t_ticks + ticks;
    t_us += acc / TICKS_PER_US;
    t_ticks = (uint8_t)(acc % TICKS_PER_US);
    if (++sub >= rate_now.n_sub) {
        sub = 0;
        if (rate_pending) {
            rate_now = rate_next;
            rate_pending = 0;
        }
        frame_tick();
    }
    OCR1A = compare_top(); /* CTC: OCR1A is not buffered, and TCNT1 has just restarted from 0 */
}

/* Kept short: ~100 of these per frame.  The frame's bookkeeping is the main loop's. */
ISR(ADC_vect)
{
    uint16_t acc = adc_acc + ADC;
    if (++adc_n < OVERSAMPLE) {
        adc_acc = acc;
        ADCSRA |= _BV(ADSC);
        return;
    }
    sampling.sum[adc_ch] = acc;
    adc_acc = 0;
    adc_n = 0;
    if (++adc_ch < N_CHANNELS) {
        ADMUX = ADMUX_BASE | adc_ch;
        ADCSRA |= _BV(ADSC);
        return;
    }
    adc_busy = 0;
    frame_done = 1;
    event_post(EVENT_FRAME);
}
