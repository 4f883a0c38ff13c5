/*
 * The rig wire protocol, version 1.1, device side (see proto.h).
 *
 * No printf: avr-libc's vfprintf would cost more flash than the rest of the
 * firmware, and 32-bit division is slow on an 8-bit core, so numbers are
 * written by subtracting powers of ten (at most 9 subtractions per digit).
 */
#include "proto.h"

/* Text and tables stay in flash on the board (2 KB of RAM is precious); the host reads them as usual. */
#ifdef __AVR__
#include <avr/pgmspace.h>
#define FLASH_U32(p) pgm_read_dword(p)
#define FLASH_CHAR(p) ((char)pgm_read_byte(p))
#else
#define PROGMEM
#define PSTR(s) (s)
#define FLASH_U32(p) (*(p))
#define FLASH_CHAR(p) (*(p))
#endif

#if TICK_HZ * 1000ULL >= 4294967296ULL
#error "TICK_HZ * 1000 must fit 32 bits: F_CPU / TIMER_PRESCALE below 4.29 MHz"
#endif

static const uint32_t POW10[9] PROGMEM = {
    1000000000UL, 100000000UL, 10000000UL, 1000000UL, 100000UL, 10000UL, 1000UL, 100UL, 10UL,
};

char *proto_put_u32(char *p, uint32_t x)
{
    uint8_t started = 0;
    for (uint8_t i = 0; i < 9; i++) {
        uint32_t pw = FLASH_U32(&POW10[i]);
        char d = '0';
        while (x >= pw) {
            x -= pw;
            d++;
        }
        if (started || d != '0') {
            *p++ = d;
            started = 1;
        }
    }
    *p++ = (char)('0' + x);
    return p;
}

static char hex_digit(uint8_t x)
{
    return (char)(x < 10 ? '0' + x : 'A' - 10 + x);
}

uint8_t proto_checksum(const char *payload, uint8_t len)
{
    uint8_t x = 0;
    while (len--)
        x ^= (uint8_t)*payload++;
    return x;
}

uint8_t proto_format_frame(char *out, uint32_t seq, uint32_t t_us, const uint16_t *values, uint8_t n)
{
    char *p = out;
    *p++ = '$';
    *p++ = 'D';
    *p++ = ',';
    p = proto_put_u32(p, seq);
    *p++ = ',';
    p = proto_put_u32(p, t_us);
    for (uint8_t i = 0; i < n; i++) {
        *p++ = ',';
        p = proto_put_u32(p, values[i]);
    }
    uint8_t cs = proto_checksum(out + 1, (uint8_t)(p - out - 1));
    *p++ = '*';
    *p++ = hex_digit(cs >> 4);
    *p++ = hex_digit(cs & 15);
    *p++ = '\n';
    *p = '\0';
    return (uint8_t)(p - out);
}

/*
 * Oversampling (Atmel AVR121): averaging N samples of a signal carrying at least
 * about half an LSB of random noise divides the noise by sqrt(N), so 16 = 4^2
 * conversions give 2 bits more than the ADC's 10.  Their sum spans 14 bits, of
 * which the lowest 2 are noise: decimating by 4 (the ">> 2") keeps the 12 that
 * carry information.  Done in one integer step together with the scale: the
 * ADC's codes are 1024 per Vref, the protocol's counts 4095 per Vref
 * ("counts * 5.0 / 4095"), so counts = sum * 4095 / (1024 * 16), rounded.  A
 * bare (sum + 2) >> 2 would read 1 part in 4096 high: up to one count at the
 * top of the range.  Rounding the sum's quarter counts to whole ones leaves a
 * still input within 1/8 count of its mean.  A perfectly quiet input gains
 * nothing: 16 equal codes give steps of 4 counts; the sensors' noise, or the
 * ADC's own, provides the dither.
 */
uint16_t proto_counts(uint16_t sum)
{
    const uint32_t den = 1024UL * OVERSAMPLE;
    return (uint16_t)(((uint32_t)sum * 4095UL + den / 2) / den);
}

uint8_t proto_line_push(struct proto_line *line, char c)
{
    if (c == '\n') {
        uint8_t was_overlong = line->overlong;
        if (line->len && line->buf[line->len - 1] == '\r')
            line->len--;
        line->buf[line->len] = '\0';
        line->len = 0;
        line->overlong = 0;
        return was_overlong ? LINE_OVERLONG : LINE_READY;
    }
    if (line->overlong)
        return LINE_PENDING;
    /* A '\r' may take the last byte: it is stripped when its '\n' comes. */
    if (line->len < CMD_MAX - 1 || (c == '\r' && line->len == CMD_MAX - 1))
        line->buf[line->len++] = c;
    else
        line->overlong = 1;
    return LINE_PENDING;
}

/* ---- timing ---- */

/* Cycles of the ADC interrupt that takes a result and starts the next conversion. */
#define ADC_ISR_CYCLES 64UL

void proto_rate_settings(uint32_t mhz, struct proto_rate *rate)
{
    uint32_t ticks = (TICK_HZ * 1000UL + mhz / 2) / mhz;
    if (ticks < 2)
        ticks = 2;
    rate->ticks = ticks;
    rate->mhz = (TICK_HZ * 1000UL + ticks / 2) / ticks;
    /* Timer1 counts 16 bits: a long period is split into n_sub nearly equal compare periods. */
    uint16_t n_sub = (uint16_t)((ticks + 65535UL) / 65536UL);
    uint32_t base = ticks / n_sub;
    rate->n_sub = n_sub;
    rate->base = (uint16_t)(base - 1); /* OCR1A value: base ticks per compare period */
    rate->extra = (uint16_t)(ticks - base * n_sub);
    /*
     * The slowest ADC clock (best accuracy: the datasheet wants 50-200 kHz for the
     * full 10 bits) whose N_CHANNELS x OVERSAMPLE conversions take at most 3/4 of the
     * period, leaving the rest for formatting and the UART; 1 MHz above that.
     */
    uint32_t period_cycles = ticks * TIMER_PRESCALE;
    uint8_t ps = 7;
    for (; ps > 4; ps--) {
        uint32_t frame_cycles = (uint32_t)N_CHANNELS * OVERSAMPLE * ((13UL << ps) + ADC_ISR_CYCLES);
        if (frame_cycles * 4UL <= period_cycles * 3UL)
            break;
    }
    rate->adc_ps_log2 = ps;
    /* Idle: the limit is checked at IDLE_CHECK_HZ or the rate, whichever is lower. */
    uint32_t every = (rate->mhz + IDLE_CHECK_HZ * 1000UL - 1) / (IDLE_CHECK_HZ * 1000UL);
    rate->idle_every = (uint8_t)(every < 1 ? 1 : every > 255 ? 255 : every);
}

/* ---- text helpers ---- */

/* A string from flash (PSTR). */
static char *put_str(char *p, const char *s)
{
    char c;
    while ((c = FLASH_CHAR(s++)))
        *p++ = c;
    return p;
}

char *proto_put_pstr(char *out, const char *pstr)
{
    return put_str(out, pstr);
}

/* Millihertz as "200", "12.5" or "333.333". */
static char *put_mhz(char *p, uint32_t mhz)
{
    p = proto_put_u32(p, mhz / 1000UL);
    uint16_t frac = (uint16_t)(mhz % 1000UL);
    if (frac) {
        *p++ = '.';
        for (uint16_t pw = 100; frac && pw; pw /= 10) {
            *p++ = (char)('0' + frac / pw);
            frac %= pw;
        }
    }
    return p;
}

/* At most max bytes of s, unprintable ones as '?', "..." when cut: replies stay one ASCII line. */
static char *put_shown(char *p, const char *s, uint8_t max)
{
    uint8_t i = 0;
    for (; s[i] && i < max; i++)
        *p++ = (s[i] >= ' ' && s[i] <= '~') ? s[i] : '?';
    if (s[i])
        p = put_str(p, PSTR("..."));
    return p;
}

static void end_line(char *p)
{
    *p++ = '\n';
    *p = '\0';
}

static uint8_t is_space(char c)
{
    return c == ' ' || c == '\t';
}

/* RAM text equal to a flash string (PSTR)? */
static uint8_t text_eq(const char *a, const char *flash)
{
    char b;
    while ((b = FLASH_CHAR(flash)) && *a == b) {
        a++;
        flash++;
    }
    return *a == FLASH_CHAR(flash);
}

/* "200", "12.5", "333.3333" as millihertz, rounded to the nearest (saturated far above any
 * rate); 0 if the text is not such a number. */
static uint8_t parse_mhz(const char *s, uint32_t *mhz)
{
    uint32_t hz = 0;
    uint8_t digits = 0;
    for (; *s >= '0' && *s <= '9'; s++) {
        if (hz < 1000000UL)
            hz = hz * 10 + (uint32_t)(*s - '0');
        digits++;
    }
    uint32_t frac = 0;
    uint8_t frac_digits = 0;
    uint8_t round_up = 0;
    if (*s == '.') {
        for (s++; *s >= '0' && *s <= '9'; s++) {
            if (frac_digits < 3)
                frac = frac * 10 + (uint32_t)(*s - '0');
            else if (frac_digits == 3)
                round_up = *s >= '5';
            frac_digits++;
        }
    }
    if (*s || !(digits || frac_digits))
        return 0;
    for (; frac_digits < 3; frac_digits++)
        frac *= 10;
    *mhz = hz >= 1000000UL ? 0xFFFFFFFFUL : hz * 1000UL + frac + round_up;
    return 1;
}

/* ---- commands ---- */

void proto_init(struct proto_state *st)
{
    proto_rate_settings(RATE_DEFAULT_MHZ, &st->rate);
    st->streaming = 0;
    for (uint8_t i = 0; i < N_VALVES; i++) {
        st->valve[i] = VALVE_HOLD;
        st->valve_next[i] = VALVE_HOLD;
        st->pmax[i] = PMAX_DEFAULT_COUNTS;
    }
    st->est_every = 0;
    st->model = 0;
    st->estimates = 0;
}

static uint8_t rate_command(struct proto_state *st, const char *arg, char *reply)
{
    char *p = reply;
    uint32_t mhz;
    if (!parse_mhz(arg, &mhz)) {
        p = put_str(p, PSTR("ERR RATE needs a number of Hz, got '"));
        p = put_shown(p, arg, 20);
        *p++ = '\'';
        end_line(p);
        return PROTO_REPLY;
    }
    if (mhz < RATE_MIN_HZ * 1000UL || mhz > (uint32_t)RATE_MAX_HZ * 1000UL) {
        p = put_str(p, PSTR("ERR RATE must be within "));
        p = proto_put_u32(p, RATE_MIN_HZ);
        p = put_str(p, PSTR(".."));
        p = proto_put_u32(p, RATE_MAX_HZ);
        p = put_str(p, PSTR(" Hz at "));
        p = proto_put_u32(p, BAUD);
        p = put_str(p, PSTR(" baud, got "));
        p = put_shown(p, arg, 20);
        end_line(p);
        return PROTO_REPLY;
    }
    proto_rate_settings(mhz, &st->rate);
    p = put_str(p, PSTR("OK RATE "));
    p = put_mhz(p, st->rate.mhz);
    end_line(p);
    return PROTO_RATE;
}

/* ---- wire protocol 1.1 commands ---- */

static const char VALVE_NAME_LIST[] PROGMEM = VALVE_NAMES;

char *proto_put_valve_name(char *out, uint8_t valve)
{
    const char *s = VALVE_NAME_LIST;
    for (uint8_t k = 0; k < valve; s++)
        if (FLASH_CHAR(s) == ':')
            k++;
    char c;
    while ((c = FLASH_CHAR(s++)) && c != ':')
        *out++ = c;
    return out;
}

/* The valve named by the word at *p ("ALL": N_VALVES), or 0xFF; *p moves past the word. */
static uint8_t valve_of(const char **p)
{
    const char *w = *p;
    uint8_t n = 0;
    while (w[n] && !is_space(w[n]))
        n++;
    *p = w + n;
    if (n == 3 && w[0] == 'A' && w[1] == 'L' && w[2] == 'L')
        return N_VALVES;
    for (uint8_t k = 0; k < N_VALVES; k++) {
        char name[CMD_MAX];
        char *end = proto_put_valve_name(name, k);
        if ((uint8_t)(end - name) == n) {
            uint8_t i = 0;
            while (i < n && name[i] == w[i])
                i++;
            if (i == n)
                return k;
        }
    }
    return 0xFF;
}

static char upper(char c)
{
    return (c >= 'a' && c <= 'z') ? (char)(c - 32) : c;
}

/* SUPPLY, HOLD or VENT (any case) as its letter, or 0. */
static uint8_t state_of(const char *w)
{
    static const char WORDS[] PROGMEM = "SUPPLY\0HOLD\0VENT\0";
    const char *x = WORDS;
    for (uint8_t k = 0; k < 3; k++) {
        uint8_t i = 0;
        while (FLASH_CHAR(x + i) && upper(w[i]) == FLASH_CHAR(x + i))
            i++;
        if (!FLASH_CHAR(x + i) && !w[i])
            return (uint8_t)FLASH_CHAR(x);
        while (FLASH_CHAR(x++))
            ;
    }
    return 0;
}

static char *put_states(char *p, const uint8_t *states)
{
    for (uint8_t i = 0; i < N_VALVES; i++)
        *p++ = (char)states[i];
    return p;
}

static uint8_t valve_command(struct proto_state *st, const char *arg, char *reply)
{
    const char *p = arg;
    uint8_t which = valve_of(&p);
    while (is_space(*p))
        p++;
    uint8_t state = state_of(p);
    if (which == 0xFF || !state) {
        char *q = put_str(reply, PSTR("ERR VALVE needs <"));
        for (uint8_t k = 0; k < N_VALVES; k++) {
            q = proto_put_valve_name(q, k);
            *q++ = '|';
        }
        q = put_str(q, PSTR("ALL> <SUPPLY|HOLD|VENT>, got '"));
        q = put_shown(q, arg, 40);
        *q++ = '\'';
        end_line(q);
        return PROTO_REPLY;
    }
    for (uint8_t k = 0; k < N_VALVES; k++)
        st->valve_next[k] = (which == N_VALVES || which == k) ? state : st->valve[k];
    end_line(put_states(put_str(reply, PSTR("OK VALVE ")), st->valve_next));
    return PROTO_VALVE;
}

static void pmax_reply(const struct proto_state *st, char *reply)
{
    char *p = put_str(reply, PSTR("OK PMAX"));
    for (uint8_t k = 0; k < N_VALVES; k++) {
        *p++ = ' ';
        p = proto_put_u32(p, st->pmax[k]);
    }
    end_line(p);
}

/* Whole counts 0..4095 separated by spaces: how many (at most max) into v, or 0xFF if malformed. */
static uint8_t parse_counts(const char *p, uint16_t *v, uint8_t max)
{
    uint8_t n = 0;
    for (;;) {
        while (is_space(*p))
            p++;
        if (!*p)
            return n;
        uint16_t x = 0;
        uint8_t digits = 0;
        for (; *p >= '0' && *p <= '9'; p++, digits++)
            if (x <= 4095)
                x = (uint16_t)(x * 10 + (*p - '0'));
        if (!digits || x > 4095 || (*p && !is_space(*p)) || n == max)
            return 0xFF;
        v[n++] = x;
    }
}

static uint8_t pmax_command(struct proto_state *st, const char *arg, char *reply)
{
    uint16_t v[N_VALVES];
    uint8_t n = parse_counts(arg, v, N_VALVES);
    if (n != 1 && n != N_VALVES) {
        char *p = put_str(reply, PSTR("ERR PMAX needs one limit or "));
        p = proto_put_u32(p, N_VALVES);
        p = put_str(p, PSTR(", in counts 0..4095, got '"));
        p = put_shown(p, arg, 40);
        *p++ = '\'';
        end_line(p);
        return PROTO_REPLY;
    }
    for (uint8_t k = 0; k < N_VALVES; k++)
        st->pmax[k] = v[n == 1 ? 0 : k];
    pmax_reply(st, reply);
    return PROTO_PMAX;
}

static uint8_t no_model(char *reply, const char *what_pstr)
{
    end_line(put_str(put_str(reply, PSTR("ERR this board carries no model, so no ")), what_pstr));
    return PROTO_REPLY;
}

static uint8_t est_command(struct proto_state *st, const char *arg, char *reply)
{
    uint16_t v[1];
    if (!st->model)
        return no_model(reply, PSTR("EST"));
    if (parse_counts(arg, v, 1) != 1 || v[0] > 255) {
        char *p = put_str(reply, PSTR("ERR EST needs a whole number of data lines 0..255, got '"));
        p = put_shown(p, arg, 20);
        *p++ = '\'';
        end_line(p);
        return PROTO_REPLY;
    }
    st->est_every = (uint8_t)v[0];
    end_line(proto_put_u32(put_str(reply, PSTR("OK EST ")), st->est_every));
    return PROTO_REPLY;
}

static void caps_reply(const struct proto_state *st, char *reply)
{
    char *p = put_str(reply, PSTR("CAPS," PROTOCOL_VERSION ",valves=" VALVE_NAMES ",pmax,events,wdt="));
    p = proto_put_u32(p, WATCHDOG_MS);
    if (st->model) {
        p = put_str(p, PSTR(",est="));
        p = put_shown(p, st->estimates, 40);
        p = put_str(p, PSTR(",model="));
        p = put_shown(p, st->model, 16);
        p = put_str(p, PSTR(",baseline"));
    }
    end_line(p);
}

/* The command word's argument: after "WORD" and spaces, or 0 when text is not that word. */
static const char *argument(const char *text, const char *word_pstr)
{
    const char *t = text;
    char c;
    while ((c = FLASH_CHAR(word_pstr++)))
        if (*t++ != c)
            return 0;
    if (*t && !is_space(*t))
        return 0;
    while (is_space(*t))
        t++;
    return t;
}

static uint8_t command_1_1(struct proto_state *st, const char *text, char *reply)
{
    const char *arg;
    if (text_eq(text, PSTR("CAPS?"))) {
        caps_reply(st, reply);
        return PROTO_REPLY;
    }
    if (text_eq(text, PSTR("VALVE?"))) {
        end_line(put_states(put_str(reply, PSTR("OK VALVE ")), st->valve));
        return PROTO_REPLY;
    }
    if ((arg = argument(text, PSTR("VALVE"))))
        return valve_command(st, arg, reply);
    if (text_eq(text, PSTR("PMAX?"))) {
        pmax_reply(st, reply);
        return PROTO_REPLY;
    }
    if ((arg = argument(text, PSTR("PMAX"))))
        return pmax_command(st, arg, reply);
    if ((arg = argument(text, PSTR("EST"))))
        return est_command(st, arg, reply);
    if (text_eq(text, PSTR("BASELINE"))) {
        if (!st->model)
            return no_model(reply, PSTR("BASELINE"));
        end_line(put_str(reply, PSTR("OK BASELINE")));
        return PROTO_BASELINE;
    }
    return PROTO_NONE;
}

uint8_t proto_command(struct proto_state *st, const char *line, char *reply)
{
    char text[CMD_MAX];
    uint8_t n = 0;
    while (is_space(*line))
        line++;
    while (*line && n < CMD_MAX - 1)
        text[n++] = *line++;
    while (n && is_space(text[n - 1]))
        n--;
    text[n] = '\0';
    reply[0] = '\0';
    if (!n)
        return PROTO_NONE;

    if (text_eq(text, PSTR("ID?"))) {
        char *p = put_str(reply, PSTR("ID," DEVICE_NAME "," FIRMWARE_VERSION "," CHANNEL_NAMES));
        end_line(p);
        return PROTO_REPLY;
    }
    if (text_eq(text, PSTR("START"))) {
        st->streaming = 1;
        end_line(put_str(reply, PSTR("OK START")));
        return PROTO_START;
    }
    if (text_eq(text, PSTR("STOP"))) {
        st->streaming = 0;
        end_line(put_str(reply, PSTR("OK STOP")));
        return PROTO_STOP;
    }
    if (n >= 4 && text[0] == 'R' && text[1] == 'A' && text[2] == 'T' && text[3] == 'E'
        && (n == 4 || is_space(text[4]))) {
        const char *arg = text + 4;
        while (is_space(*arg))
            arg++;
        return rate_command(st, arg, reply);
    }
    uint8_t action = WIRE_1_1 ? command_1_1(st, text, reply) : PROTO_NONE;
    if (action != PROTO_NONE)
        return action;
    char *p = put_str(reply, PSTR("ERR unknown command '"));
    p = put_shown(p, text, 40);
    *p++ = '\'';
    end_line(p);
    return PROTO_REPLY;
}

void proto_overlong_reply(char *reply)
{
    char *p = put_str(reply, PSTR("ERR command longer than "));
    p = proto_put_u32(p, CMD_MAX - 1);
    end_line(put_str(p, PSTR(" bytes")));
}

/* ---- log lines ---- */

void proto_banner(char *out)
{
    char *p = put_str(out, PSTR("# " DEVICE_NAME " " FIRMWARE_VERSION " ready, "));
    p = proto_put_u32(p, N_CHANNELS);
    p = put_str(p, PSTR(" channels, "));
    p = proto_put_u32(p, BAUD);
    end_line(put_str(p, PSTR(" baud")));
}

void proto_start_log(char *out, const struct proto_state *st)
{
    char *p = put_str(out, PSTR("# streaming "));
    p = proto_put_u32(p, N_CHANNELS);
    p = put_str(p, PSTR(" channels at "));
    p = put_mhz(p, st->rate.mhz);
    p = put_str(p, PSTR(" Hz, ADC clock "));
    p = proto_put_u32(p, (F_CPU >> st->rate.adc_ps_log2) / 1000UL);
    p = put_str(p, PSTR(" kHz, "));
    p = proto_put_u32(p, OVERSAMPLE);
    end_line(put_str(p, PSTR(" conversions per value")));
}

void proto_stop_log(char *out, const struct proto_stats *s)
{
    char *p = put_str(out, PSTR("# stopped: "));
    p = proto_put_u32(p, s->sent);
    p = put_str(p, PSTR(" frames sent, "));
    p = proto_put_u32(p, s->uart_full + s->adc_late + s->unformatted);
    p = put_str(p, PSTR(" dropped ("));
    p = proto_put_u32(p, s->uart_full);
    p = put_str(p, PSTR(" uart full, "));
    p = proto_put_u32(p, s->adc_late);
    p = put_str(p, PSTR(" adc late, "));
    p = proto_put_u32(p, s->unformatted);
    p = put_str(p, PSTR(" unformatted), sampling "));
    p = proto_put_u32(p, s->sampling_us_max);
    end_line(put_str(p, PSTR(" us per frame at most")));
}

/* ---- wire protocol 1.1 lines ---- */

/* "*HH\n" after the payload out[1..p), and the NUL; the line's length. */
static uint8_t sign(char *out, char *p)
{
    uint8_t cs = proto_checksum(out + 1, (uint8_t)(p - out - 1));
    *p++ = '*';
    *p++ = hex_digit(cs >> 4);
    *p++ = hex_digit(cs & 15);
    *p++ = '\n';
    *p = '\0';
    return (uint8_t)(p - out);
}

static char *event_head(char *out, uint32_t n, uint32_t t_us, const char *kind_pstr)
{
    char *p = put_str(out, PSTR("$E,"));
    p = proto_put_u32(p, n);
    *p++ = ',';
    p = proto_put_u32(p, t_us);
    *p++ = ',';
    return put_str(p, kind_pstr);
}

uint8_t proto_event_valve(char *out, uint32_t n, uint32_t t_us, const uint8_t *states, const char *cause_pstr)
{
    char *p = event_head(out, n, t_us, PSTR("VALVE,"));
    p = put_states(p, states);
    *p++ = ',';
    return sign(out, put_str(p, cause_pstr));
}

uint8_t proto_event_pmax(char *out, uint32_t n, uint32_t t_us, uint8_t valve, uint16_t counts)
{
    char *p = proto_put_valve_name(event_head(out, n, t_us, PSTR("PMAX,")), valve);
    *p++ = ',';
    return sign(out, proto_put_u32(p, counts));
}

uint8_t proto_event_reset(char *out, uint32_t n, uint32_t t_us, const char *cause_pstr)
{
    return sign(out, put_str(event_head(out, n, t_us, PSTR("RESET,")), cause_pstr));
}

uint8_t proto_event_baseline(char *out, uint32_t n, uint32_t t_us, const char *cause_pstr, const uint32_t *sum,
                             uint16_t count)
{
    /* The frames and each channel's sum of counts, not rounded means: the host divides and so
     * works from the very baseline the chip does. */
    char *p = put_str(event_head(out, n, t_us, PSTR("BASELINE,")), cause_pstr);
    *p++ = ',';
    p = proto_put_u32(p, count);
    for (uint8_t i = 0; i < N_CHANNELS; i++) {
        *p++ = ',';
        p = proto_put_u32(p, sum[i]);
    }
    return sign(out, p);
}

/* v / 10^d with d decimals (d <= 9), "-0.000123" style. */
static char *put_fixed(char *p, int32_t v, uint8_t d)
{
    uint32_t mag = v < 0 ? (uint32_t)(-(v + 1)) + 1U : (uint32_t)v;
    if (v < 0)
        *p++ = '-';
    uint32_t scale = d ? FLASH_U32(&POW10[9 - d]) : 1UL;
    p = proto_put_u32(p, mag / scale);
    if (d) {
        uint32_t frac = mag % scale;
        *p++ = '.';
        for (uint32_t pw = scale / 10; pw; pw /= 10) {
            uint8_t digit = (uint8_t)(frac / pw);
            *p++ = (char)('0' + digit);
            frac -= digit * pw;
        }
    }
    return p;
}

uint8_t proto_format_estimate(char *out, uint32_t seq, uint32_t t_us, const int32_t *values, const uint8_t *decimals,
                              uint8_t n, uint16_t flags)
{
    char *p = put_str(out, PSTR("$S,"));
    p = proto_put_u32(p, seq);
    *p++ = ',';
    p = proto_put_u32(p, t_us);
    for (uint8_t k = 0; k < n; k++) {
        *p++ = ',';
        p = put_fixed(p, values[k], decimals[k]);
    }
    *p++ = ',';
    return sign(out, proto_put_u32(p, flags));
}

uint8_t proto_over_limit(const struct proto_state *st, const uint16_t *counts)
{
    uint8_t over = 0;
    for (uint8_t k = 0; k < N_VALVES; k++)
        if (counts[k] > st->pmax[k] && st->valve[k] != VALVE_VENT)
            over |= (uint8_t)(1U << k);
    return over;
}
