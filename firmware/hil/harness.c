/*
 * labcli_hil: the rig firmware (an AVR ELF) on simavr's ATmega328P, its analog
 * inputs driven in lockstep by a driver program (labcli.core.sim.hil) that owns the
 * physical model of the rig.
 *
 * usage: labcli_hil [options] FIRMWARE.elf
 *   --mcu NAME         simavr core (atmega328p)
 *   --freq HZ          clock (16000000)
 *   --vref-mv MV       AVCC, the ADC's reference (5000)
 *   --channels N       analog inputs ADC0..N-1 the driver feeds (6)
 *   --slice-us US      simulated time per voltage sample (1000)
 *   --adc-noise-lsb X  rms noise of the ADC itself, 10-bit LSB (0.5)
 *   --seed N           seed of that noise (0)
 *   --uart-bits N      bits per byte on the wire: start + 8 data + stop (10)
 *
 * Messages travel on stdin (from the driver) and on the stdout the harness was
 * started with; whatever simavr prints goes to stderr.  Each is a type byte, a
 * little-endian uint32 payload length, then the payload.
 *
 * Driver -> harness
 *   'V'  n x channels float32, volts: the inputs over the next n slices of
 *        simulated time, each value the input at its slice's end.  The AVR runs
 *        only as far as voltages have come, so the driver sets the pace.
 *   'R'  bytes for the AVR's UART receiver (host -> device)
 *   'Q'  stop
 * Harness -> driver
 *   'H'  text, once the ELF is loaded: "mcu=atmega328p freq=16000000 ..."
 *   'T'  uint64 cycle count: the AVR has run to the end of one 'V' message's slices
 *   'U'  bytes the AVR's UART sent (device -> host), before each 'T' and every 1 KiB
 *   'B'  text, when the firmware sets a baud rate: "baud=117647.06 byte_us=85.000"
 *   'P'  uint64 cycle count, port letter, value: the firmware wrote PORTB or PORTD
 *        (the valves' pins), once at the value it wrote
 *   'E'  text: why the simulation ended (the firmware stopped or crashed); exit status 2
 *
 * The ADC.  simavr reads an input in millivolts and converts it as
 * floor(mV * 1023 / Vref).  The ATmega328P's own transfer function (datasheet,
 * "ADC Accuracy Definitions") has its first transition at 0.5 LSB and 1024
 * codes per Vref: code = round(V * 1024 / Vref).  When a conversion starts,
 * the harness takes the input at that instant (linear between slices), adds the
 * ADC's own noise, works out the datasheet's code and hands simavr the one
 * millivolt value that simavr converts to that code.
 *
 * The UART.  simavr 1.6 times a byte as 11 bits (it counts a parity bit even
 * with parity off); an 8N1 byte is 10 bits on the wire, so the harness sets
 * the byte time from the divider the firmware chose, --uart-bits bits long.
 */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/select.h>
#include <unistd.h>

#include "avr_adc.h"
#include "avr_ioport.h"
#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_io.h"
#include "sim_irq.h"

#define MAX_CHANNELS 8
#define RING_SLICES (1u << 14) /* voltages held: the driver stays far fewer slices ahead */
#define MAX_SPANS 4096
#define UART_FLUSH_AT 1024

struct options {
    const char *elf;
    const char *mcu;
    uint32_t freq;
    uint32_t vref_mv;
    unsigned channels;
    uint32_t slice_us;
    double adc_noise_lsb;
    uint64_t seed;
    unsigned uart_bits;
};

static struct options opt = {NULL, "atmega328p", 16000000, 5000, 6, 1000, 0.5, 0, 10};
static avr_t *avr;
static int out_fd = -1;
static uint64_t slice_cycles;

/* Voltages: slice k (k = 0, 1, ...) ends at cycle (k + 1) * slice_cycles. */
static float volts[RING_SLICES][MAX_CHANNELS];
static uint64_t n_slices;

/* Ends of the 'V' messages not yet reported with 'T', oldest first. */
static uint64_t spans[MAX_SPANS];
static unsigned span_head, span_count;

static avr_irq_t *adc_in[MAX_CHANNELS];
static avr_irq_t *uart_in;
static uint8_t uart_buf[64 * 1024];
static size_t uart_len;
static uint8_t *rx_queue;
static size_t rx_len, rx_cap;
static int rx_blocked = 1; /* until the UART says its receiver is on and has room */
static uint64_t rng_state;

/* ------------------------------------------------------------------ output */

static void write_all(const void *p, size_t n)
{
    const uint8_t *b = p;
    while (n) {
        ssize_t k = write(out_fd, b, n);
        if (k < 0) {
            if (errno == EINTR)
                continue;
            exit(3); /* the driver is gone */
        }
        b += k;
        n -= (size_t)k;
    }
}

static void send(char type, const void *payload, uint32_t len)
{
    uint8_t head[5] = {(uint8_t)type, (uint8_t)len, (uint8_t)(len >> 8), (uint8_t)(len >> 16),
                       (uint8_t)(len >> 24)};
    write_all(head, sizeof head);
    if (len)
        write_all(payload, len);
}

static void sendf(char type, const char *fmt, ...)
{
    char text[256];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    send(type, text, (uint32_t)(n < 0 ? 0 : n >= (int)sizeof text ? (int)sizeof text - 1 : n));
}

static void flush_uart(void)
{
    if (uart_len) {
        send('U', uart_buf, (uint32_t)uart_len);
        uart_len = 0;
    }
}

static void fail(const char *why)
{
    flush_uart();
    sendf('E', "%s", why);
    exit(2);
}

/* ------------------------------------------------------------------ ADC */

static double gauss(void)
{
    /* xorshift64* then Box-Muller: reproducible from --seed, no libc state. */
    double u[2];
    for (int i = 0; i < 2; i++) {
        rng_state ^= rng_state >> 12;
        rng_state ^= rng_state << 25;
        rng_state ^= rng_state >> 27;
        u[i] = ((rng_state * 2685821657736338717ULL) >> 11) * (1.0 / 9007199254740992.0);
    }
    return sqrt(-2.0 * log(u[0] + 1e-300)) * cos(2.0 * M_PI * u[1]);
}

static double volts_at(unsigned ch, uint64_t cycle)
{
    if (!n_slices)
        return 0.0;
    uint64_t k = cycle / slice_cycles;
    if (k >= n_slices) /* only after a sleep overshot the last slice: hold */
        return volts[(n_slices - 1) % RING_SLICES][ch];
    double end = volts[k % RING_SLICES][ch];
    double start = k ? volts[(k - 1) % RING_SLICES][ch] : end;
    double frac = (double)(cycle - k * slice_cycles) / (double)slice_cycles;
    return start + (end - start) * frac;
}

static void on_adc_start(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    union {
        avr_adc_mux_t mux;
        uint32_t v;
    } e = {.v = value};
    if (e.mux.kind != ADC_MUX_SINGLE || e.mux.src >= opt.channels)
        return;
    double lsb = opt.vref_mv / 1000.0 / 1024.0;
    double v = volts_at(e.mux.src, avr->cycle) + opt.adc_noise_lsb * lsb * gauss();
    double x = floor(v / lsb + 0.5);
    uint32_t code = x < 0 ? 0 : x > 1023 ? 1023 : (uint32_t)x;
    uint32_t mv = (code * opt.vref_mv + 1022) / 1023; /* simavr: floor(mv * 1023 / Vref) == code */
    avr_raise_irq(adc_in[e.mux.src], mv);
}

/* ------------------------------------------------------------------ pins */

static void on_port_write(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    uint8_t msg[10];
    uint64_t cycle = avr->cycle;
    memcpy(msg, &cycle, 8); /* little-endian host */
    msg[8] = (uint8_t)(uintptr_t)param;
    msg[9] = (uint8_t)value;
    flush_uart(); /* bytes sent before the pins moved reach the driver first */
    send('P', msg, sizeof msg);
}

/* ------------------------------------------------------------------ UART */

static void on_uart_byte(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    uart_buf[uart_len++] = (uint8_t)value;
    if (uart_len >= UART_FLUSH_AT)
        flush_uart();
}

static void feed_rx(void)
{
    size_t i = 0;
    while (!rx_blocked && i < rx_len)
        avr_raise_irq(uart_in, rx_queue[i++]); /* may raise XOFF, which sets rx_blocked */
    memmove(rx_queue, rx_queue + i, rx_len - i);
    rx_len -= i;
}

static void on_uart_xon(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)value;
    (void)param;
    rx_blocked = 0;
    feed_rx();
}

static void on_uart_xoff(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    rx_blocked = value != 0;
}

static void on_ubrr_write(avr_t *a, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)addr;
    (void)v;
    avr_uart_t *u = param;
    /* simavr's own handler ran first and set its 11-bit byte time: set the real one. */
    uint32_t ubrr = avr_regbit_get(a, u->ubrrl) | ((uint32_t)avr_regbit_get(a, u->ubrrh) << 8);
    uint32_t cycles_per_bit = (ubrr + 1) * (avr_regbit_get(a, u->u2x) ? 8 : 16);
    u->cycles_per_byte = (avr_cycle_count_t)cycles_per_bit * opt.uart_bits;
    sendf('B', "baud=%.2f byte_us=%.3f", (double)opt.freq / cycles_per_bit,
          1e6 * (double)u->cycles_per_byte / opt.freq);
}

static avr_uart_t *find_uart0(void)
{
    for (avr_io_t *io = avr->io_port; io; io = io->next)
        if (!strcmp(io->kind, "uart") && ((avr_uart_t *)io)->name == '0')
            return (avr_uart_t *)io;
    return NULL;
}

/* ------------------------------------------------------------------ input */

static uint8_t *in_buf;
static size_t in_len, in_cap;

/* A timer at the end of the oldest unreported span stops a sleeping AVR there. */
static avr_cycle_count_t span_timer(struct avr_t *a, avr_cycle_count_t when, void *param)
{
    (void)a;
    (void)param;
    for (unsigned i = 0; i < span_count; i++) {
        uint64_t end = spans[(span_head + i) % MAX_SPANS];
        if (end > when)
            return end;
    }
    return 0;
}

static void add_voltages(const uint8_t *p, uint32_t len)
{
    uint32_t per = 4u * opt.channels;
    if (len % per || !len)
        fail("a 'V' message must hold whole slices of float32 volts");
    for (uint32_t n = len / per; n--; p += per) {
        float *row = volts[n_slices % RING_SLICES];
        memcpy(row, p, per);
        n_slices++;
    }
    if (span_count == MAX_SPANS)
        fail("too many 'V' messages ahead of the simulation");
    uint64_t end = n_slices * slice_cycles;
    spans[(span_head + span_count++) % MAX_SPANS] = end;
    if (avr_cycle_timer_status(avr, span_timer, NULL) == 0 && end > avr->cycle)
        avr_cycle_timer_register(avr, end - avr->cycle, span_timer, NULL);
}

static void add_rx(const uint8_t *p, uint32_t len)
{
    if (rx_len + len > rx_cap) {
        rx_cap = (rx_len + len) * 2;
        rx_queue = realloc(rx_queue, rx_cap);
        if (!rx_queue)
            fail("out of memory");
    }
    memcpy(rx_queue + rx_len, p, len);
    rx_len += len;
    feed_rx();
}

/* Handle every complete message in the input buffer. */
static void handle_input(void)
{
    size_t pos = 0;
    while (in_len - pos >= 5) {
        const uint8_t *h = in_buf + pos;
        uint32_t len = h[1] | (uint32_t)h[2] << 8 | (uint32_t)h[3] << 16 | (uint32_t)h[4] << 24;
        if (in_len - pos - 5 < len)
            break;
        switch (h[0]) {
        case 'V':
            add_voltages(h + 5, len);
            break;
        case 'R':
            add_rx(h + 5, len);
            break;
        case 'Q':
            flush_uart();
            exit(0);
        default:
            fail("unknown message type from the driver");
        }
        pos += 5 + len;
    }
    memmove(in_buf, in_buf + pos, in_len - pos);
    in_len -= pos;
}

/* Read what stdin has; block for it when `wait`.  End of input stops the harness. */
static void read_input(int wait)
{
    if (!wait) {
        fd_set fds;
        FD_ZERO(&fds);
        FD_SET(0, &fds);
        struct timeval zero = {0, 0};
        if (select(1, &fds, NULL, NULL, &zero) <= 0)
            return;
    }
    if (in_cap - in_len < 65536) {
        in_cap = in_cap * 2 + 65536;
        in_buf = realloc(in_buf, in_cap);
        if (!in_buf)
            fail("out of memory");
    }
    ssize_t k;
    do
        k = read(0, in_buf + in_len, in_cap - in_len);
    while (k < 0 && errno == EINTR);
    if (k <= 0)
        exit(0);
    in_len += (size_t)k;
}

/* ------------------------------------------------------------------ main */

static void report_spans(void)
{
    while (span_count && avr->cycle >= spans[span_head]) {
        uint64_t end = spans[span_head];
        span_head = (span_head + 1) % MAX_SPANS;
        span_count--;
        flush_uart();
        send('T', &end, sizeof end); /* little-endian host */
        read_input(0);
        handle_input();
    }
}

static void no_sleep(avr_t *a, avr_cycle_count_t how_long)
{
    /* simavr would sleep the wall-clock time the AVR sleeps; the driver paces instead. */
    (void)a;
    (void)how_long;
}

static void usage(void)
{
    fprintf(stderr, "usage: labcli_hil [--mcu NAME] [--freq HZ] [--vref-mv MV] [--channels N] "
                    "[--slice-us US] [--adc-noise-lsb X] [--seed N] [--uart-bits N] FIRMWARE.elf\n");
    exit(1);
}

static void parse_args(int argc, char **argv)
{
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *val = i + 1 < argc ? argv[i + 1] : NULL;
        if (a[0] != '-') {
            opt.elf = a;
            continue;
        }
        if (!val)
            usage();
        i++;
        if (!strcmp(a, "--mcu"))
            opt.mcu = val;
        else if (!strcmp(a, "--freq"))
            opt.freq = (uint32_t)strtoul(val, NULL, 10);
        else if (!strcmp(a, "--vref-mv"))
            opt.vref_mv = (uint32_t)strtoul(val, NULL, 10);
        else if (!strcmp(a, "--channels"))
            opt.channels = (unsigned)strtoul(val, NULL, 10);
        else if (!strcmp(a, "--slice-us"))
            opt.slice_us = (uint32_t)strtoul(val, NULL, 10);
        else if (!strcmp(a, "--adc-noise-lsb"))
            opt.adc_noise_lsb = strtod(val, NULL);
        else if (!strcmp(a, "--seed"))
            opt.seed = strtoull(val, NULL, 10);
        else if (!strcmp(a, "--uart-bits"))
            opt.uart_bits = (unsigned)strtoul(val, NULL, 10);
        else
            usage();
    }
    if (!opt.elf || !opt.freq || !opt.vref_mv || !opt.channels || opt.channels > MAX_CHANNELS
        || !opt.slice_us || opt.adc_noise_lsb < 0 || opt.uart_bits < 7 || opt.uart_bits > 13)
        usage();
}

static void setup(void)
{
    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(opt.elf, &fw))
        fail("cannot read the firmware ELF");
    snprintf(fw.mmcu, sizeof fw.mmcu, "%s", opt.mcu);
    fw.frequency = opt.freq;
    avr = avr_make_mcu_by_name(fw.mmcu);
    if (!avr)
        fail("simavr does not know that MCU");
    avr_init(avr);
    avr_load_firmware(avr, &fw);
    avr->frequency = opt.freq;
    avr->vcc = avr->avcc = avr->aref = opt.vref_mv;
    avr->log = LOG_WARNING;
    avr->sleep = no_sleep;
    slice_cycles = (uint64_t)opt.freq * opt.slice_us / 1000000u;
    rng_state = opt.seed * 0x9E3779B97F4A7C15ULL + 0x2545F4914F6CDD1DULL;

    uint32_t flags = 0; /* no console echo of the UART, no sleeping on polled flags */
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), on_uart_byte, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON), on_uart_xon, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF), on_uart_xoff, NULL);
    uart_in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    avr_uart_t *u = find_uart0();
    if (!u)
        fail("simavr's core has no UART0");
    avr_register_io_write(avr, u->ubrrl.reg, on_ubrr_write, u);
    for (unsigned ch = 0; ch < opt.channels; ch++)
        adc_in[ch] = avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0 + ch);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), IOPORT_IRQ_REG_PORT), on_port_write,
                            (void *)(uintptr_t)'B');
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('D'), IOPORT_IRQ_REG_PORT), on_port_write,
                            (void *)(uintptr_t)'D');
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_OUT_TRIGGER), on_adc_start, NULL);
}

int main(int argc, char **argv)
{
    parse_args(argc, argv);
    /* simavr prints to stdout: keep the real stdout for messages, send the rest to stderr. */
    out_fd = dup(1);
    if (out_fd < 0 || dup2(2, 1) < 0)
        return 1;
    setup();
    sendf('H', "mcu=%s freq=%lu channels=%u slice_us=%lu vref_mv=%lu adc_noise_lsb=%g uart_bits=%u", opt.mcu,
          (unsigned long)opt.freq, opt.channels, (unsigned long)opt.slice_us, (unsigned long)opt.vref_mv,
          opt.adc_noise_lsb, opt.uart_bits);
    for (;;) {
        uint64_t granted = n_slices * slice_cycles;
        while (avr->cycle < granted) {
            int state = avr_run(avr);
            if (state == cpu_Done)
                fail("the firmware stopped (it returned from main or slept with interrupts off)");
            if (state == cpu_Crashed)
                fail("the firmware crashed");
            if (span_count && avr->cycle >= spans[span_head])
                report_spans();
            granted = n_slices * slice_cycles;
        }
        report_spans();
        flush_uart();
        /* Out of voltages: wait for the driver's next ones. */
        while (n_slices * slice_cycles <= avr->cycle) {
            read_input(1);
            handle_input();
        }
    }
}
