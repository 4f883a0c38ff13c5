/*
 * Work the interrupts leave for the main loop.  The main loop sleeps until an
 * interrupt and goes straight back to sleep unless one of these is set, so the
 * hundred or so interrupts per frame that leave nothing to do cost a few cycles.
 */
#ifndef LABCLI_EVENTS_H
#define LABCLI_EVENTS_H

#include <stdint.h>

#define EVENT_RX 1    /* the UART received a byte */
#define EVENT_FRAME 2 /* the ADC finished a frame's conversions */

extern volatile uint8_t events;

/* From an interrupt (interrupts are off there). */
static inline void event_post(uint8_t event)
{
    events |= event;
}

#endif
