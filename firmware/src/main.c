/*
 * Reference firmware of the labcli rig wire protocol, version 1, for an
 * ATmega328P at 16 MHz (Arduino Uno class).  See firmware/README.md.
 *
 * The main loop answers commands, formats finished frames and sleeps; the
 * interrupts do the timing (Timer1), the sampling (ADC) and the bytes (USART0).
 * A data line is queued whole or not at all: when the transmit ring has no
 * room the frame is dropped and its seq skipped, so the host counts it lost.
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/power.h>
#include <avr/sleep.h>
#include <avr/wdt.h>

#include "config.h"
#include "events.h"
#include "proto.h"
#include "sampler.h"
#include "uart.h"

/* A watchdog reset leaves the watchdog on; switch it off before anything else runs. */
void early_wdt_off(void) __attribute__((naked, used, section(".init3")));
void early_wdt_off(void)
{
    MCUSR = 0;
    wdt_disable();
}

volatile uint8_t events;

static struct proto_state state;
static struct proto_line line;
static uint32_t n_sent, n_uart_full;
static char text[PROTO_REPLY_MAX];

static void send_frame(const struct frame *f)
{
    char buf[PROTO_FRAME_MAX];
    uint16_t counts[N_CHANNELS];
    for (uint8_t i = 0; i < N_CHANNELS; i++)
        counts[i] = proto_counts(f->sum[i]);
    uint8_t n = proto_format_frame(buf, f->seq, f->t_us, counts, N_CHANNELS);
    if (uart_tx_free() < n) {
        n_uart_full++; /* the line is slower than the rate: drop the whole frame */
        return;
    }
    uart_write(buf, n);
    n_sent++;
}

static void command(const char *cmd)
{
    switch (proto_command(&state, cmd, text)) {
    case PROTO_RATE:
        sampler_set_rate(&state.rate);
        break;
    case PROTO_START:
        uart_write_wait(text); /* "OK START", then the stream's settings, then frames */
        proto_start_log(text, &state);
        n_sent = 0;
        n_uart_full = 0;
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
        break;
    }
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

int main(void)
{
    /* Nothing else on the chip is used. */
    power_twi_disable();
    power_spi_disable();
    power_timer0_disable();
    power_timer2_disable();
    set_sleep_mode(SLEEP_MODE_IDLE);
    proto_init(&state);
    uart_init();
    sampler_init(&state.rate);
    wdt_enable(WDTO_1S);
    sei();
    proto_banner(text);
    uart_write_wait(text);

    for (;;) {
        wdt_reset();
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
        if ((work & EVENT_FRAME) && sampler_take(&f))
            send_frame(&f);
    }
}
