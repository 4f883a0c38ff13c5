/*
 * Cycles of the model on the chip (make MODEL=model.h model-bench; tests/benchmarks/
 * bench_firmware_model.py runs it on simavr).  PORTB is written before and after each piece
 * of work, and the harness reports every port write with its cycle count:
 *
 *   PORTB = 1   model_predict on one of 8 realistic inputs (the pressures 1-3 % off their baseline)
 *   PORTB = 64  the same with a motion into the baseline (a load after the first: the friction
 *               terms read it; the same motion each time, as for the estimates of one baseline)
 *   PORTB = 2   one float multiply      PORTB = 4  one float add     PORTB = 8  one float divide
 *   PORTB = 16  one sinf                PORTB = 32 one sqrtf
 *   PORTB = 0   after each
 *
 * The inputs are volatile so that nothing is computed at compile time; the cycles of the
 * surrounding loads and stores are in each figure (a few dozen, the same for all).
 */
#include <avr/io.h>
#include <math.h>

#include "model.h"

static volatile float P0[4] = {0.300f, 0.305f, 0.298f, 0.302f};
static volatile float th0[2] = {0.012f, -0.021f};
static volatile float motion[2] = {0.009f, -0.004f};
static volatile float scale[8] = {0.99f, 1.01f, 0.985f, 1.02f, 0.97f, 1.03f, 0.995f, 1.005f};
static volatile float a = 0.3f, b = 1.7f, r;
static struct model_out out;

int main(void)
{
    DDRB = 0xFF;
    for (uint8_t i = 0;; i = (uint8_t)((i + 1) & 7)) {
        float p0[4], p[4], t[2] = {th0[0], th0[1]}, moved[2] = {motion[0], motion[1]};
        for (uint8_t k = 0; k < 4; k++) {
            p0[k] = P0[k];
            p[k] = P0[k] * scale[(i + k) & 7];
        }
        PORTB = 1;
        model_predict(p0, p, t, 0, &out);
        PORTB = 0;
        PORTB = 64;
        model_predict(p0, p, t, moved, &out);
        PORTB = 0;
        PORTB = 2;
        r = a * b;
        PORTB = 0;
        PORTB = 4;
        r = a + b;
        PORTB = 0;
        PORTB = 8;
        r = a / b;
        PORTB = 0;
        PORTB = 16;
        r = sinf(a);
        PORTB = 0;
        PORTB = 32;
        r = sqrtf(a);
        PORTB = 0;
    }
}
