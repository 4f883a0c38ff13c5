/*
 * Reference firmware of the labcli rig wire protocol, version 1.1, for an
 * ATmega328P at 16 MHz (Arduino Uno class).  See firmware/README.md.
 *
 * The main loop answers commands, formats finished frames, checks the pressure
 * limit on every frame (streaming or not), drives the valves and, built with a
 * model (make MODEL=model.h), estimates the joint angles and the tip force; it
 * sleeps when nothing is left.  The interrupts do the timing (Timer1), the
 * sampling (ADC) and the bytes (USART0); the watchdog's interrupt vents every
 * chamber when the main loop hangs, and its reset follows a second later.
 * A data line is queued whole or not at all: when the transmit ring has no room
 * the frame is dropped and its seq skipped, so the host counts it lost.
 */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <avr/power.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include <string.h>

#include "config.h"
#include "events.h"
#include "proto.h"
#include "sampler.h"
#include "uart.h"
#include "valves.h"
#ifdef MODEL_HEADER
#include "onchip.h"
#endif

/* Why the chip last reset, kept from before the C runtime starts (it clears .bss). */
uint8_t boot_mcusr __attribute__((section(".noinit")));

/* A watchdog reset leaves the watchdog on; switch it off before anything else runs. */
void early_wdt_off(void) __attribute__((naked, used, section(".init3")));
void early_wdt_off(void)
{
    boot_mcusr = MCUSR;
    MCUSR = 0;
    wdt_disable();
}

#if PROTO_EVENT_MAX > PROTO_REPLY_MAX
#error "event lines are formatted in the reply buffer"
#endif

volatile uint8_t events;
static volatile uint8_t wdt_vented;

static struct proto_state state;
static struct proto_line line;
static uint32_t n_sent, n_uart_full, n_events;
static char text[PROTO_REPLY_MAX];

/* ------------------------------------------------------------------ the watchdog */

/* Interrupt and reset mode, 1 s: the interrupt vents, the next time-out resets. */
static void watchdog_on(void)
{
    uint8_t sreg = SREG;
    cli();
    wdt_reset();
    /* The timed sequence: WDCE then the new settings within four cycles. */
    __asm__ __volatile__("sts %0, %1\n\t"
                         "sts %0, %2\n\t"
                         :
                         : "n"(_SFR_MEM_ADDR(WDTCSR)), "r"((uint8_t)(_BV(WDCE) | _BV(WDE))),
                           "r"((uint8_t)(_BV(WDIE) | _BV(WDE) | _BV(WDP2) | _BV(WDP1)))
                         : "memory");
    SREG = sreg;
}

ISR(WDT_vect)
{
    /* The main loop has not been round for WATCHDOG_MS: whatever it was doing, the air goes. */
    valves_vent_now();
    wdt_vented = 1;
}

/* ------------------------------------------------------------------ limits in EEPROM */

struct stored_limits {
    uint16_t magic;
    uint16_t pmax[N_VALVES];
    uint16_t check;
};
static struct stored_limits EEMEM ee_limits;
#define LIMITS_MAGIC 0x4C31U

static uint16_t limits_check(const struct stored_limits *l)
{
    uint16_t c = l->magic;
    for (uint8_t k = 0; k < N_VALVES; k++)
        c = (uint16_t)(((c << 1) | (c >> 15)) ^ l->pmax[k]);
    return c;
}

static void limits_load(void)
{
    struct stored_limits l;
    eeprom_read_block(&l, &ee_limits, sizeof l);
    if (l.magic != LIMITS_MAGIC || l.check != limits_check(&l))
        return; /* never stored (a fresh chip reads 0xFF): the default */
    for (uint8_t k = 0; k < N_VALVES; k++)
        if (l.pmax[k] <= 4095)
            state.pmax[k] = l.pmax[k];
}

static void limits_store(void)
{
    struct stored_limits l;
    l.magic = LIMITS_MAGIC;
    memcpy(l.pmax, state.pmax, sizeof l.pmax);
    l.check = limits_check(&l);
    eeprom_update_block(&l, &ee_limits, sizeof l);
}

/* ------------------------------------------------------------------ events and valves */

static void send_event(uint8_t len)
{
    (void)len;
    n_events++;
    uart_write_wait(text);
}

static void set_valves(const uint8_t *wanted, const char *cause_pstr)
{
    if (!memcmp(wanted, state.valve, N_VALVES))
        return;
    valves_set(wanted);
    memcpy(state.valve, wanted, N_VALVES);
    send_event(proto_event_valve(text, n_events, sampler_now_us(), state.valve, cause_pstr));
#ifdef MODEL_HEADER
    onchip_valves_changed();
#endif
}

/* A chamber the host left supplying this long since its last VALVE command is held by the board:
 * a host that dies while the chambers fill never leaves them on the regulator unattended. */
#ifndef SUPPLY_MAX_MS
#define SUPPLY_MAX_MS 60000UL
#endif
static uint32_t supplied_at_us; /* the host's last VALVE command (sampler clock) */

static void check_supply(uint32_t t_us)
{
    if (!memchr(state.valve, VALVE_SUPPLY, N_VALVES))
        return;
    /* Signed: a frame whose conversions began before the command is not after it (wraps after 35 min). */
    if ((int32_t)(t_us - supplied_at_us) < (int32_t)(SUPPLY_MAX_MS * 1000UL))
        return;
    uint8_t wanted[N_VALVES];
    for (uint8_t k = 0; k < N_VALVES; k++)
        wanted[k] = state.valve[k] == VALVE_SUPPLY ? VALVE_HOLD : state.valve[k];
    set_valves(wanted, PSTR("timeout"));
}

/* Vent every valve reading above its limit, with a PMAX event each. */
static void check_limit(const uint16_t *counts)
{
    uint8_t over = WIRE_1_1 ? proto_over_limit(&state, counts) : 0;
    if (!over)
        return;
    uint8_t wanted[N_VALVES];
    memcpy(wanted, state.valve, N_VALVES);
    for (uint8_t k = 0; k < N_VALVES; k++) {
        if (over & (1U << k)) {
            send_event(proto_event_pmax(text, n_events, sampler_now_us(), k, counts[k]));
            wanted[k] = VALVE_VENT;
        }
    }
    set_valves(wanted, PSTR("pmax"));
}

/* ------------------------------------------------------------------ frames */

static void send_frame(const struct frame *f, const uint16_t *counts)
{
    char buf[PROTO_FRAME_MAX];
    uint8_t n = proto_format_frame(buf, f->seq, f->t_us, counts, N_CHANNELS);
    if (uart_tx_free() < n) {
        n_uart_full++; /* the line is slower than the rate: drop the whole frame */
        return;
    }
    uart_write(buf, n);
    n_sent++;
}

static void handle_frame(const struct frame *f)
{
    uint16_t counts[N_CHANNELS];
    for (uint8_t i = 0; i < N_CHANNELS; i++)
        counts[i] = proto_counts(f->sum[i]);
    check_limit(counts);
    if (WIRE_1_1)
        check_supply(f->t_us);
    if (f->streamed)
        send_frame(f, counts);
#ifdef MODEL_HEADER
    if (onchip_frame(f, counts, &state))
        send_event(onchip_baseline_event(text, n_events, f->t_us));
#endif
}

/* ------------------------------------------------------------------ commands */

static void command(const char *cmd)
{
#ifdef LABCLI_TEST_COMMANDS
    if (!strcmp(cmd, "TEST HANG")) /* a test build's hung main loop, for the watchdog's test */
        for (;;)
            ;
#endif
    switch (proto_command(&state, cmd, text)) {
    case PROTO_RATE:
        sampler_set_rate(&state.rate);
#ifdef MODEL_HEADER
        onchip_rate(&state.rate);
#endif
        break;
    case PROTO_START:
        uart_write_wait(text); /* "OK START", then the stream's settings, then frames */
        proto_start_log(text, &state);
        n_sent = 0;
        n_uart_full = 0;
#ifdef MODEL_HEADER
        onchip_start();
#endif
        sampler_start();
        break;
    case PROTO_STOP: {
        sampler_stop();
        struct proto_stats stats;
        sampler_stats(&stats);
        stats.sent = n_sent;
        stats.uart_full = n_uart_full;
        char log[PROTO_REPLY_MAX];
        proto_stop_log(log, &stats);
        uart_write_wait(log); /* before "OK STOP", so the host still reads it as this stream's */
#ifdef MODEL_HEADER
        onchip_stop_log(log);
        uart_write_wait(log);
#endif
        break;
    }
    case PROTO_VALVE: {
        char reply[PROTO_REPLY_MAX];
        memcpy(reply, text, sizeof reply); /* the event is formatted in text first */
        set_valves(state.valve_next, PSTR("host"));
        supplied_at_us = sampler_now_us();
        uart_write_wait(reply);
        return;
    }
    case PROTO_PMAX:
        limits_store();
        break;
#ifdef MODEL_HEADER
    case PROTO_BASELINE:
        onchip_baseline();
        break;
#endif
    default:
        break;
    }
    uart_write_wait(text);
}

static void receive(char c)
{
    switch (proto_line_push(&line, c)) {
    case LINE_READY:
        command(line.buf);
        break;
    case LINE_OVERLONG:
        proto_overlong_reply(text);
        uart_write_wait(text);
        break;
    default:
        break;
    }
}

/* ------------------------------------------------------------------ power-up */

static void boot(void)
{
    uint8_t vent = (boot_mcusr & _BV(WDRF)) != 0; /* a hung loop was reset: keep the air out */
    for (uint8_t k = 0; k < N_VALVES; k++)
        state.valve[k] = vent ? VALVE_VENT : VALVE_HOLD;
    valves_init(state.valve);
    limits_load();
    proto_banner(text);
    uart_write_wait(text);
    if (!WIRE_1_1)
        return;
    if (boot_mcusr & (_BV(WDRF) | _BV(BORF))) {
        const char *cause = (boot_mcusr & _BV(WDRF)) ? PSTR("wdt") : PSTR("brownout");
        send_event(proto_event_reset(text, n_events, sampler_now_us(), cause));
    }
    if (vent)
        send_event(proto_event_valve(text, n_events, sampler_now_us(), state.valve, PSTR("wdt")));
}

int main(void)
{
    /* Nothing else on the chip is used. */
    power_twi_disable();
    power_spi_disable();
    power_timer0_disable();
    power_timer2_disable();
    set_sleep_mode(SLEEP_MODE_IDLE);
    proto_init(&state);
#ifdef MODEL_HEADER
    onchip_init(&state);
#endif
    uart_init();
    sampler_init(&state.rate);
    sei();
    boot();
    watchdog_on();

    for (;;) {
        wdt_reset();
        if (!(WDTCSR & _BV(WDIE)))
            WDTCSR |= _BV(WDIE); /* re-armed after its interrupt, should the loop have come back */
        if (wdt_vented) {
            wdt_vented = 0;
            uint8_t vent[N_VALVES];
            memset(vent, VALVE_VENT, N_VALVES);
            memset(state.valve, VALVE_HOLD, N_VALVES); /* so that the event is sent */
            set_valves(vent, PSTR("wdt"));
        }
        cli();
        uint8_t work = events;
        if (!work) {
            /* Nothing to do: sleep until an interrupt (sei's one-instruction delay makes
             * this safe against one arriving in between). */
            sleep_enable();
            sei();
            sleep_cpu();
            sleep_disable();
            continue;
        }
        events = 0;
        sei();
        if (work & EVENT_RX) {
            int16_t c;
            while ((c = uart_getc()) >= 0)
                receive((char)c);
        }
        struct frame f;
        while (sampler_take(&f))
            handle_frame(&f);
#ifdef MODEL_HEADER
        onchip_estimate(&state); /* the newest frame's; frames that came meanwhile wait in the queue */
#endif
    }
}
