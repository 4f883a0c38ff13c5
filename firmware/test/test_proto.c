/*
 * Host unit tests of the device-side protocol code (src/proto.c), known answers only.
 * Run by `make -C firmware test`; tests/core/test_firmware_host.py runs it and, through
 * proto_tool, checks the same code against labcli.core.wire on random inputs.
 */
#include <stdio.h>
#include <string.h>

#include "proto.h"

static int checks, failures;

#define CHECK(cond)                                                                \
    do {                                                                           \
        checks++;                                                                  \
        if (!(cond)) {                                                             \
            failures++;                                                            \
            fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond); \
        }                                                                          \
    } while (0)

#define CHECK_STR(got, want)                                                        \
    do {                                                                            \
        checks++;                                                                   \
        if (strcmp((got), (want))) {                                                \
            failures++;                                                             \
            fprintf(stderr, "%s:%d: got \"%s\", want \"%s\"\n", __FILE__, __LINE__, (got), (want)); \
        }                                                                           \
    } while (0)

static void test_checksum_and_frame(void)
{
    /* docs/wire-protocol.md's example. */
    const char *payload = "D,0,1000,1556,1560,1549,1551,2048,2047";
    CHECK(proto_checksum(payload, (uint8_t)strlen(payload)) == 0x76);
    CHECK(proto_checksum("", 0) == 0);
    CHECK(proto_checksum("\xff\x0f", 2) == 0xf0);

    char out[PROTO_FRAME_MAX];
    const uint16_t v[6] = {1556, 1560, 1549, 1551, 2048, 2047};
    uint8_t n = proto_format_frame(out, 0, 1000, v, 6);
    CHECK_STR(out, "$D,0,1000,1556,1560,1549,1551,2048,2047*76\n");
    CHECK(n == strlen(out));

    /* The widest line: both counters at 2^32 - 1, values of five digits. */
    const uint16_t wide[6] = {65535, 65535, 65535, 65535, 65535, 65535};
    n = proto_format_frame(out, 4294967295UL, 4294967295UL, wide, 6);
    CHECK(n == strlen(out) && n < PROTO_FRAME_MAX);
    CHECK(strncmp(out, "$D,4294967295,4294967295,65535,", 31) == 0);
    const uint16_t zero[6] = {0, 0, 0, 0, 0, 0};
    proto_format_frame(out, 0, 0, zero, 6);
    CHECK(strncmp(out, "$D,0,0,0,0,0,0,0,0*", 19) == 0);
    CHECK(out[19] == "0123456789ABCDEF"[proto_checksum("D,0,0,0,0,0,0,0,0", 17) >> 4]);
}

static void test_put_u32(void)
{
    char buf[12];
    const uint32_t xs[] = {0, 9, 10, 99, 100, 1000000000UL, 4294967295UL, 4000000000UL};
    const char *want[] = {"0", "9", "10", "99", "100", "1000000000", "4294967295", "4000000000"};
    for (unsigned i = 0; i < sizeof xs / sizeof xs[0]; i++) {
        *proto_put_u32(buf, xs[i]) = '\0';
        CHECK_STR(buf, want[i]);
    }
}

static void test_counts(void)
{
    /* counts = sum * 4095 / 16384, rounded: 16 equal codes c give c * 4095 / 1024. */
    CHECK(proto_counts(0) == 0);
    CHECK(proto_counts(16 * 1023) == 4091); /* the ADC's top code: 1023/1024 of Vref */
    CHECK(proto_counts(16 * 512) == 2048);  /* half of Vref: 2.5 V */
    CHECK(proto_counts(16 * 205) == 820);   /* 1.0 V (204.8 codes) reads 819-820 */
    /* One code more in the sum moves the result by a quarter count: two extra bits. */
    CHECK(proto_counts(16 * 512 + 2) == 2048);
    CHECK(proto_counts(16 * 512 + 6) == 2049);
    for (uint32_t sum = 0; sum <= 16 * 1023; sum++) {
        double exact = sum * 4095.0 / 16384.0;
        double got = proto_counts((uint16_t)sum);
        if (got - exact > 0.5 || exact - got > 0.5) {
            CHECK(0);
            break;
        }
    }
}

static uint8_t feed(struct proto_line *l, const char *s)
{
    uint8_t r = LINE_PENDING;
    while (*s)
        r = proto_line_push(l, *s++);
    return r;
}

static void test_line_assembler(void)
{
    struct proto_line l = {{0}, 0, 0};
    CHECK(feed(&l, "ID?") == LINE_PENDING);
    CHECK(feed(&l, "\n") == LINE_READY);
    CHECK_STR(l.buf, "ID?");
    CHECK(feed(&l, "STOP\r\n") == LINE_READY);
    CHECK_STR(l.buf, "STOP");
    CHECK(feed(&l, "\n") == LINE_READY);
    CHECK_STR(l.buf, "");

    char longest[CMD_MAX + 2];
    memset(longest, 'x', CMD_MAX - 1);
    strcpy(longest + CMD_MAX - 1, "\r\n"); /* 63 bytes and a '\r' still fit */
    CHECK(feed(&l, longest) == LINE_READY);
    CHECK(strlen(l.buf) == CMD_MAX - 1);
    memset(longest, 'x', CMD_MAX);
    strcpy(longest + CMD_MAX, "\n");
    CHECK(feed(&l, longest) == LINE_OVERLONG);
    CHECK(feed(&l, "START\n") == LINE_READY); /* the next line is unharmed */
    CHECK_STR(l.buf, "START");
}

static void test_rate_settings(void)
{
    struct proto_rate r;
    proto_rate_settings(200000, &r);
    CHECK(r.ticks == 10000 && r.mhz == 200000 && r.n_sub == 1 && r.base == 9999 && r.extra == 0);
    CHECK(r.adc_ps_log2 == 5); /* 500 kHz: 96 conversions in 2.9 ms of the 5 ms period */
    proto_rate_settings(1000, &r); /* 1 Hz: 2e6 ticks as 31 compare periods */
    CHECK(r.ticks == 2000000UL && r.n_sub == 31);
    CHECK((uint32_t)(r.base + 1) * r.n_sub + r.extra == r.ticks);
    CHECK(r.adc_ps_log2 == 7);
    proto_rate_settings(333333, &r); /* 333.333 Hz: 6000 ticks, exactly 333.333... Hz */
    CHECK(r.ticks == 6000 && r.mhz == 333333);
    proto_rate_settings(30500, &r); /* just over 2^16 ticks per period */
    CHECK(r.n_sub == 2 && (uint32_t)(r.base + 1) * 2 + r.extra == r.ticks);
    proto_rate_settings(260000, &r);
    CHECK(r.adc_ps_log2 == 5); /* 500 kHz up to 260 Hz, */
    proto_rate_settings(261000, &r);
    CHECK(r.adc_ps_log2 == 4); /* 1 MHz above */
    proto_rate_settings(72000, &r);
    CHECK(r.adc_ps_log2 == 7); /* 125 kHz up to 72 Hz, */
    proto_rate_settings(73000, &r);
    CHECK(r.adc_ps_log2 == 6); /* 250 kHz above, */
    proto_rate_settings(139000, &r);
    CHECK(r.adc_ps_log2 == 6); /* up to 139 Hz */
    proto_rate_settings(140000, &r);
    CHECK(r.adc_ps_log2 == 5);
    proto_rate_settings(100000, &r);
    CHECK(r.adc_ps_log2 == 6);
    proto_rate_settings(50000, &r);
    CHECK(r.adc_ps_log2 == 7);
    CHECK(r.idle_every == 1); /* 50 Hz: every period checked when idle */
    proto_rate_settings(200000, &r);
    CHECK(r.idle_every == 4);
    proto_rate_settings(201000, &r);
    CHECK(r.idle_every == 5); /* never less often than IDLE_CHECK_HZ */
    proto_rate_settings(1000, &r);
    CHECK(r.idle_every == 1);
}

static void expect(struct proto_state *st, const char *cmd, uint8_t action, const char *reply)
{
    char out[PROTO_REPLY_MAX];
    uint8_t got = proto_command(st, cmd, out);
    CHECK(got == action);
    CHECK_STR(out, reply);
}

static void test_commands(void)
{
    struct proto_state st;
    proto_init(&st);
    CHECK(st.rate.mhz == 200000 && !st.streaming);
    expect(&st, "ID?", PROTO_REPLY, "ID,mckibben-2dof,1.1-avr,P_L1,P_R1,P_L2,P_R2,POT1,POT2\n");
    expect(&st, "  ID?\t", PROTO_REPLY, "ID,mckibben-2dof,1.1-avr,P_L1,P_R1,P_L2,P_R2,POT1,POT2\n");
    expect(&st, "", PROTO_NONE, "");
    expect(&st, "   ", PROTO_NONE, "");
    expect(&st, "RATE 100", PROTO_RATE, "OK RATE 100\n");
    CHECK(st.rate.mhz == 100000);
    expect(&st, "RATE 12.5", PROTO_RATE, "OK RATE 12.5\n");
    expect(&st, "RATE   160.0", PROTO_RATE, "OK RATE 160\n");
    expect(&st, "RATE 150", PROTO_RATE, "OK RATE 150.004\n"); /* 13333 ticks: the rate actually set */
    expect(&st, "RATE 1", PROTO_RATE, "OK RATE 1\n");
    expect(&st, "RATE 199.9999", PROTO_RATE, "OK RATE 200\n");
    expect(&st, "RATE .5e1", PROTO_REPLY, "ERR RATE needs a number of Hz, got '.5e1'\n");
    expect(&st, "RATE abc", PROTO_REPLY, "ERR RATE needs a number of Hz, got 'abc'\n");
    expect(&st, "RATE", PROTO_REPLY, "ERR RATE needs a number of Hz, got ''\n");
    expect(&st, "RATE -5", PROTO_REPLY, "ERR RATE needs a number of Hz, got '-5'\n");
    expect(&st, "RATE .", PROTO_REPLY, "ERR RATE needs a number of Hz, got '.'\n");
    char want[PROTO_REPLY_MAX];
    snprintf(want, sizeof want, "ERR RATE must be within 1..%lu Hz at %lu baud, got 0\n",
             (unsigned long)RATE_MAX_HZ, (unsigned long)BAUD);
    expect(&st, "RATE 0", PROTO_REPLY, want);
    snprintf(want, sizeof want, "ERR RATE must be within 1..%lu Hz at %lu baud, got 0.999\n",
             (unsigned long)RATE_MAX_HZ, (unsigned long)BAUD);
    expect(&st, "RATE 0.999", PROTO_REPLY, want);
    snprintf(want, sizeof want, "ERR RATE must be within 1..%lu Hz at %lu baud, got 99999999999\n",
             (unsigned long)RATE_MAX_HZ, (unsigned long)BAUD);
    expect(&st, "RATE 99999999999", PROTO_REPLY, want);
    CHECK(st.rate.mhz == 200000); /* refused rates leave the rate alone */
    expect(&st, "START", PROTO_START, "OK START\n");
    CHECK(st.streaming);
    expect(&st, "START", PROTO_START, "OK START\n");
    expect(&st, "STOP", PROTO_STOP, "OK STOP\n");
    CHECK(!st.streaming);
    expect(&st, "STOP", PROTO_STOP, "OK STOP\n");
    expect(&st, "start", PROTO_REPLY, "ERR unknown command 'start'\n");
    expect(&st, "RATES 5", PROTO_REPLY, "ERR unknown command 'RATES 5'\n");
    expect(&st, "START now", PROTO_REPLY, "ERR unknown command 'START now'\n");
    expect(&st, "\x01\xff?", PROTO_REPLY, "ERR unknown command '?\?\?'\n");
    expect(&st, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz", PROTO_REPLY,
           "ERR unknown command 'ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmn...'\n");
    char out[PROTO_REPLY_MAX];
    proto_overlong_reply(out);
    CHECK_STR(out, "ERR command longer than 63 bytes\n");
}

static void test_log_lines(void)
{
    struct proto_state st;
    char out[PROTO_REPLY_MAX];
    proto_init(&st);
    proto_banner(out);
    char want[PROTO_REPLY_MAX];
    snprintf(want, sizeof want, "# mckibben-2dof 1.1-avr ready, 6 channels, %lu baud\n", (unsigned long)BAUD);
    proto_banner(out);
    CHECK_STR(out, want);
    proto_start_log(out, &st);
    CHECK_STR(out, "# streaming 6 channels at 200 Hz, ADC clock 500 kHz, 16 conversions per value\n");
    struct proto_stats s = {1000, 3, 2, 1, 2875};
    proto_stop_log(out, &s);
    CHECK_STR(out, "# stopped: 1000 frames sent, 6 dropped (3 uart full, 2 adc late, 1 unformatted), "
                   "sampling 2875 us per frame at most\n");
    struct proto_stats most = {4294967295UL, 4294967295UL, 4294967295UL, 4294967295UL, 65535};
    proto_stop_log(out, &most);
    CHECK(strlen(out) < PROTO_REPLY_MAX);
}

static void test_valves_and_limits(void)
{
    struct proto_state st;
    proto_init(&st);
    CHECK(st.valve[0] == 'H' && st.valve[3] == 'H' && st.pmax[2] == 3112 && !st.est_every);
    expect(&st, "CAPS?", PROTO_REPLY, "CAPS,1.1,valves=P_L1:P_R1:P_L2:P_R2,pmax,events,wdt=1000\n");
    expect(&st, "VALVE?", PROTO_REPLY, "OK VALVE HHHH\n");
    expect(&st, "VALVE P_L2 VENT", PROTO_VALVE, "OK VALVE HHVH\n");
    CHECK(!memcmp(st.valve_next, "HHVH", 4) && !memcmp(st.valve, "HHHH", 4)); /* the caller applies it */
    memcpy(st.valve, "SSSV", 4);
    expect(&st, "VALVE ALL hold", PROTO_VALVE, "OK VALVE HHHH\n");
    expect(&st, "VALVE   P_R1\tSupply", PROTO_VALVE, "OK VALVE SSSV\n");
    expect(&st, "VALVE?", PROTO_REPLY, "OK VALVE SSSV\n");
    const char *need = "ERR VALVE needs <P_L1|P_R1|P_L2|P_R2|ALL> <SUPPLY|HOLD|VENT>, got '";
    char want[PROTO_REPLY_MAX];
    const char *bad[] = {"P_X VENT", "ALL", "ALL OPEN", "P_L VENT", "P_L11 VENT", "ALL VENTS", ""};
    for (unsigned i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char cmd[CMD_MAX];
        snprintf(cmd, sizeof cmd, "VALVE %s", bad[i]);
        snprintf(want, sizeof want, "%s%s'\n", need, bad[i]);
        expect(&st, cmd, PROTO_REPLY, want);
    }
    expect(&st, "VALVES", PROTO_REPLY, "ERR unknown command 'VALVES'\n");
    expect(&st, "PMAX?", PROTO_REPLY, "OK PMAX 3112 3112 3112 3112\n");
    expect(&st, "PMAX 2000", PROTO_PMAX, "OK PMAX 2000 2000 2000 2000\n");
    expect(&st, "PMAX 1 20 300 4095", PROTO_PMAX, "OK PMAX 1 20 300 4095\n");
    const char *bad_pmax[] = {"", "1 2", "4096", "-1", "1.5", "1 2 3 4 5", "0x10", "99999999999"};
    for (unsigned i = 0; i < sizeof bad_pmax / sizeof bad_pmax[0]; i++) {
        char cmd[CMD_MAX];
        snprintf(cmd, sizeof cmd, "PMAX %s", bad_pmax[i]);
        snprintf(want, sizeof want, "ERR PMAX needs one limit or 4, in counts 0..4095, got '%s'\n", bad_pmax[i]);
        expect(&st, cmd, PROTO_REPLY, want);
    }
    CHECK(st.pmax[0] == 1 && st.pmax[3] == 4095); /* refused limits leave the limits alone */
    expect(&st, "EST 1", PROTO_REPLY, "ERR this board carries no model, so no EST\n");
    expect(&st, "BASELINE", PROTO_REPLY, "ERR this board carries no model, so no BASELINE\n");
    st.model = "3f09a1c2";
    st.estimates = "theta1:theta2:Fx:Fy";
    expect(&st, "CAPS?", PROTO_REPLY,
           "CAPS,1.1,valves=P_L1:P_R1:P_L2:P_R2,pmax,events,wdt=1000,est=theta1:theta2:Fx:Fy,model=3f09a1c2,"
           "baseline\n");
    expect(&st, "EST 4", PROTO_REPLY, "OK EST 4\n");
    CHECK(st.est_every == 4);
    expect(&st, "EST 256", PROTO_REPLY, "ERR EST needs a whole number of data lines 0..255, got '256'\n");
    expect(&st, "BASELINE", PROTO_BASELINE, "OK BASELINE\n");

    /* The limit: above it and not venting. */
    uint16_t counts[N_CHANNELS] = {2, 20, 301, 4095, 0, 0};
    memcpy(st.valve, "SSSS", 4);
    CHECK(proto_over_limit(&st, counts) == 0x5); /* 2 > 1 and 301 > 300; 20 and 4095 are at, not above */
    memcpy(st.valve, "SSVH", 4);
    CHECK(proto_over_limit(&st, counts) == 0x1); /* a venting chamber is left alone */
}

static void test_event_and_estimate_lines(void)
{
    char out[PROTO_EVENT_MAX];
    uint8_t n = proto_event_valve(out, 7, 12345, (const uint8_t *)"SSHV", "host");
    CHECK_STR(out, "$E,7,12345,VALVE,SSHV,host*39\n");
    CHECK(n == strlen(out));
    proto_event_pmax(out, 0, 4294967295UL, 3, 3200);
    CHECK(!strncmp(out, "$E,0,4294967295,PMAX,P_R2,3200*", 31));
    proto_event_reset(out, 1, 0, "wdt");
    CHECK(!strncmp(out, "$E,1,0,RESET,wdt*", 17));
    const uint32_t sum[N_CHANNELS] = {155600, 3, 0, 4294967295UL, 2, 99999};
    n = proto_event_baseline(out, 4294967295UL, 4294967295UL, "release", sum, 65535);
    CHECK(!strncmp(out, "$E,4294967295,4294967295,BASELINE,release,65535,155600,3,0,4294967295,2,99999*", 78));
    CHECK(n == strlen(out) && n < PROTO_EVENT_MAX);

    char est[PROTO_ESTIMATE_MAX];
    const int32_t v[4] = {123, -5, -2147483647L - 1, 2147483647L};
    const uint8_t d[4] = {6, 6, 4, 0};
    n = proto_format_estimate(est, 9, 5000, v, d, 4, 513);
    CHECK(!strncmp(est, "$S,9,5000,0.000123,-0.000005,-214748.3648,2147483647,513*", 57));
    CHECK(n == strlen(est) && n < PROTO_ESTIMATE_MAX);
    const int32_t w[2] = {31415926, -1000000};
    proto_format_estimate(est, 0, 0, w, d, 2, 0);
    CHECK(!strncmp(est, "$S,0,0,31.415926,-1.000000,0*", 29));
}

int main(void)
{
    test_checksum_and_frame();
    test_put_u32();
    test_counts();
    test_line_assembler();
    test_rate_settings();
    test_commands();
    test_log_lines();
    test_valves_and_limits();
    test_event_and_estimate_lines();
    if (failures) {
        printf("%d of %d checks failed\n", failures, checks);
        return 1;
    }
    printf("%d checks passed\n", checks);
    return 0;
}
