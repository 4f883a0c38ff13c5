/*
 * The chambers' valves: each chamber has an inlet coil (to the regulator) and an exhaust coil
 * (to the atmosphere) on the pins config.h names; SUPPLY opens the inlet, VENT the exhaust,
 * HOLD neither, and no state opens both.  The main supply valve is open while any chamber is
 * supplied, and the Uno's LED shows it.
 *
 * A change is two port writes: first every coil that must switch off, then the ones that must
 * switch on (break before make), so a chamber going from supply to vent is never open to both
 * sides, even for the microseconds between writes.
 */
#include <avr/interrupt.h>
#include <avr/io.h>

#include "valves.h"

static const uint8_t INLET_D[N_VALVES] = VALVE_INLET_D;
static const uint8_t INLET_B[N_VALVES] = VALVE_INLET_B;
static const uint8_t EXHAUST_D[N_VALVES] = VALVE_EXHAUST_D;
static const uint8_t EXHAUST_B[N_VALVES] = VALVE_EXHAUST_B;

static uint8_t mask_of(const uint8_t *bits)
{
    uint8_t m = 0;
    for (uint8_t i = 0; i < N_VALVES; i++)
        m |= bits[i];
    return m;
}

#define OURS_D (mask_of(INLET_D) | mask_of(EXHAUST_D))
#define OURS_B (mask_of(INLET_B) | mask_of(EXHAUST_B) | VALVE_MAIN_B | VALVE_LED_B)

static void images(const uint8_t *states, uint8_t *d, uint8_t *b)
{
    *d = 0;
    *b = 0;
    for (uint8_t i = 0; i < N_VALVES; i++) {
        if (states[i] == 'S') {
            *d |= INLET_D[i];
            *b |= INLET_B[i] | VALVE_MAIN_B | VALVE_LED_B;
        } else if (states[i] == 'V') {
            *d |= EXHAUST_D[i];
            *b |= EXHAUST_B[i];
        }
    }
}

void valves_set(const uint8_t *states)
{
    uint8_t d, b;
    images(states, &d, &b);
    uint8_t ours_d = OURS_D, ours_b = OURS_B;
    uint8_t sreg = SREG;
    cli();
    PORTD &= (uint8_t)(~ours_d | d); /* off first: only what stays on is left on */
    PORTB &= (uint8_t)(~ours_b | b);
    PORTD |= d;
    PORTB |= b;
    SREG = sreg;
}

void valves_init(const uint8_t *states)
{
    /* D2 and D3 are also INT0 and INT1, level-triggered at reset: never enabled here, but made
     * edge-triggered so that nothing watches their low level (simavr polls it every cycle, which
     * slowed the simulated board twentyfold). */
    EICRA = _BV(ISC11) | _BV(ISC10) | _BV(ISC01) | _BV(ISC00);
    valves_set(states);
    DDRD |= OURS_D;
    DDRB |= OURS_B;
}

void valves_vent_now(void)
{
    uint8_t vent[N_VALVES];
    for (uint8_t i = 0; i < N_VALVES; i++)
        vent[i] = 'V';
    valves_set(vent);
}
