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
 * A frame's conversions go into the next free slot of a queue of FRAME_QUEUE
 * frames; the main loop copies them out (sampler_take), oldest first.  A tick
 * that finds the queue full drops its frame ("unformatted"): the main loop,
 * busy with a model estimate, may fall a few frames behind without loss.
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

/* ADC state: the frame being sampled (queue[q_head]), then queued for the main loop. */
#define FRAME_QUEUE 4
static volatile uint8_t adc_busy;
static struct frame queue[FRAME_QUEUE];
static uint32_t queue_tick[FRAME_QUEUE];
static volatile uint8_t q_head, q_count; /* next slot to sample into; frames finished, waiting */
static uint8_t adc_ch, adc_n;
static uint16_t adc_acc;

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
    streaming = 1;
    sei();
}

void sampler_stop(void)
{
    cli();
    streaming = 0;
    /* Frames under way or queued still go through the limit check, but are not sent. */
    for (uint8_t i = 0; i < FRAME_QUEUE; i++)
        queue[i].streamed = 0;
    sei();
}

/* The free-running tick count now (the timer interrupt may be pending).  Interrupts off. */
static uint32_t ticks_now(void)
{
    uint16_t tcnt = TCNT1;
    uint32_t now = ticks_total + tcnt;
    if ((TIFR1 & _BV(OCF1A)) && tcnt < OCR1A / 2)
        now += OCR1A + 1UL;
    return now;
}

uint32_t sampler_ticks(void)
{
    uint8_t sreg = SREG;
    cli();
    uint32_t now = ticks_now();
    SREG = sreg;
    return now;
}

uint32_t sampler_now_us(void)
{
    uint8_t sreg = SREG;
    cli();
    uint32_t now = t_us + (uint32_t)(((uint16_t)t_ticks + TCNT1) / TICKS_PER_US);
    SREG = sreg;
    return now;
}

uint8_t sampler_take(struct frame *out)
{
    uint8_t got = 0;
    cli();
    if (q_count) {
        /* The oldest finished frame: q_count behind the slot being sampled (or the next one). */
        uint8_t tail = (uint8_t)((q_head + FRAME_QUEUE - q_count) % FRAME_QUEUE);
        *out = queue[tail];
        q_count--;
        got = 1;
        /* From the tick to the hand-over: the conversions, plus however long the main loop took. */
        uint32_t us = (ticks_now() - queue_tick[tail]) / TICKS_PER_US;
        if (out->streamed && us > sampling_us_max)
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

/* A frame period begins: a streamed frame's seq is used whatever becomes of the frame. */
static uint8_t idle_count;

static void frame_tick(void)
{
    uint8_t on = streaming;
    uint32_t s = seq;
    if (on)
        seq++;
    else if (++idle_count < rate_now.idle_every)
        return; /* idle: the limit needs only a few checks a second */
    idle_count = 0;
    if (adc_busy) {
        n_adc_late += on; /* the previous frame's conversions are still running */
        return;
    }
    if (q_count >= FRAME_QUEUE) {
        n_unformatted += on; /* the main loop has fallen FRAME_QUEUE frames behind */
        return;
    }
    struct frame *f = &queue[q_head];
    f->seq = s;
    f->t_us = t_us;
    f->streamed = on;
    queue_tick[q_head] = ticks_total;
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
    queue[q_head].sum[adc_ch] = acc;
    adc_acc = 0;
    adc_n = 0;
    if (++adc_ch < N_CHANNELS) {
        ADMUX = ADMUX_BASE | adc_ch;
        ADCSRA |= _BV(ADSC);
        return;
    }
    adc_busy = 0;
    q_head = (uint8_t)((q_head + 1) % FRAME_QUEUE);
    q_count++;
    event_post(EVENT_FRAME);
}
