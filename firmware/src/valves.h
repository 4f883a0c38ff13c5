/*
 * The chambers' valves (wire protocol 1.1): two coils per chamber on the pins of config.h.
 * States are the protocol's letters, 'S' supply, 'H' hold, 'V' vent.
 */
#ifndef LABCLI_VALVES_H
#define LABCLI_VALVES_H

#include <stdint.h>

#include "config.h"

/* The pins as outputs, every valve in states[]. */
void valves_init(const uint8_t *states);

/* Every valve to states[]; coils that close switch off before those that open switch on. */
void valves_set(const uint8_t *states);

/* Every chamber to the atmosphere: from the watchdog's interrupt too (no state touched). */
void valves_vent_now(void);

#endif
