/*
 * The device-side protocol code (src/proto.c) behind a line-oriented pipe, for
 * the pytest cross-checks against labcli.core.wire (tests/core/test_firmware_host.py).
 * One request per input line, one answer line per request:
 *
 *   F <seq> <t_us> <v1> ... <vn>   the data line proto_format_frame makes (n <= 16)
 *   C <hex bytes>                  proto_checksum of those bytes, two hex digits
 *   K <sum>                        proto_counts(sum)
 *   R <millihertz>                 ticks mhz n_sub base extra adc_ps_log2
 *   L <hex bytes>                  a command line: "<action> <reply as hex>"
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"

static size_t unhex(const char *s, char *out, size_t cap)
{
    size_t n = 0;
    while (s[0] && s[1] && n < cap) {
        unsigned v;
        if (sscanf(s, "%2x", &v) != 1)
            break;
        out[n++] = (char)v;
        s += 2;
    }
    return n;
}

static void answer(const char *req, struct proto_state *st)
{
    char out[PROTO_REPLY_MAX + PROTO_FRAME_MAX];
    char *end;
    switch (req[0]) {
    case 'F': {
        uint32_t seq = strtoul(req + 1, &end, 10);
        uint32_t t_us = strtoul(end, &end, 10);
        uint16_t v[16];
        uint8_t n = 0;
        while (n < 16) {
            char *next;
            unsigned long x = strtoul(end, &next, 10);
            if (next == end)
                break;
            v[n++] = (uint16_t)x;
            end = next;
        }
        proto_format_frame(out, seq, t_us, v, n);
        fputs(out, stdout);
        return;
    }
    case 'C': {
        char bytes[512];
        size_t n = unhex(req + 2, bytes, sizeof bytes);
        printf("%02X\n", proto_checksum(bytes, (uint8_t)n));
        return;
    }
    case 'K':
        printf("%u\n", proto_counts((uint16_t)strtoul(req + 1, NULL, 10)));
        return;
    case 'R': {
        struct proto_rate r;
        proto_rate_settings(strtoul(req + 1, NULL, 10), &r);
        printf("%lu %lu %u %u %u %u\n", (unsigned long)r.ticks, (unsigned long)r.mhz, r.n_sub, r.base,
               r.extra, r.adc_ps_log2);
        return;
    }
    case 'L': {
        char line[CMD_MAX];
        size_t n = unhex(req + 2, line, sizeof line - 1);
        line[n] = '\0';
        uint8_t action = proto_command(st, line, out);
        printf("%u ", action);
        for (const char *p = out; *p; p++)
            printf("%02X", (unsigned char)*p);
        putchar('\n');
        return;
    }
    default:
        printf("?\n");
    }
}

int main(void)
{
    struct proto_state st;
    proto_init(&st);
    char req[4096];
    while (fgets(req, sizeof req, stdin)) {
        req[strcspn(req, "\n")] = '\0';
        answer(req, &st);
        fflush(stdout);
    }
    return 0;
}
