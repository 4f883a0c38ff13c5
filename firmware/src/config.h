/*
 * Build-time settings of the reference rig firmware (ATmega328P, Arduino Uno class).
 *
 * Everything here can be overridden on the make command line, e.g.
 *   make -C firmware BAUD=1000000 BUILD=build/1M
 * The protocol code (proto.c) includes this file too, so the host tests see
 * the same limits as the board.
 */
#ifndef LABCLI_CONFIG_H
#define LABCLI_CONFIG_H

#ifndef F_CPU
#define F_CPU 16000000UL
#endif

#ifndef BAUD
#define BAUD 115200UL
#endif

/* The reference rig (docs/wire-protocol.md): four pressures on A0-A3, two potentiometers on A4-A5. */
#define DEVICE_NAME "mckibben-2dof"
#ifdef WIRE_PROTOCOL_1_0
/* A 1.0 board (no 1.1 command, no event line), built for the tests of a 1.1 host against one. */
#define FIRMWARE_VERSION "1.0-avr"
#define WIRE_1_1 0
#else
#define FIRMWARE_VERSION "1.1-avr"
#define WIRE_1_1 1
#endif
#define PROTOCOL_VERSION "1.1"
#define CHANNEL_NAMES "P_L1,P_R1,P_L2,P_R2,POT1,POT2"
#define N_CHANNELS 6

/*
 * Valves (wire protocol 1.1): one per chamber, on the first N_VALVES channels (the pressures),
 * each made of two coils, inlet (to the regulator) and exhaust (to the atmosphere):
 * SUPPLY = inlet open, HOLD = both closed, VENT = exhaust open; never both open.
 * A pin high energises its coil through a driver (README: Valves).  D10 opens the main supply
 * valve while any chamber is supplied, and the Uno's LED (D13) shows it.
 *
 *   chamber  inlet      exhaust
 *   P_L1     D2  PD2    D3  PD3
 *   P_R1     D4  PD4    D5  PD5
 *   P_L2     D6  PD6    D7  PD7
 *   P_R2     D8  PB0    D9  PB1
 *   main supply D10 PB2, LED D13 PB5
 *
 * labcli.core.sim.hil reads the same map off the simulated pins (VALVE_PINS there).
 */
#define N_VALVES 4
#define VALVE_NAMES "P_L1:P_R1:P_L2:P_R2"
/* Each chamber's coils as bits of PORTD and PORTB, in VALVE_NAMES order. */
#define VALVE_INLET_D {_BV(2), _BV(4), _BV(6), 0}
#define VALVE_INLET_B {0, 0, 0, _BV(0)}
#define VALVE_EXHAUST_D {_BV(3), _BV(5), _BV(7), 0}
#define VALVE_EXHAUST_B {0, 0, 0, _BV(1)}
#define VALVE_MAIN_B _BV(2) /* main supply valve */
#define VALVE_LED_B _BV(5)  /* the Uno's LED */

/* The pressure limit at power-up until a PMAX is stored in EEPROM: 0.7 MPa on the reference
 * calibration (819 + 0.7 / (5 / 16380) counts), the AVR's and the simulated board's default. */
#ifndef PMAX_DEFAULT_COUNTS
#define PMAX_DEFAULT_COUNTS 3112U
#endif

/* Not streaming, the pressures are still sampled for the limit, at about this rate (Hz). */
#define IDLE_CHECK_HZ 50UL

/* The watchdog: 1 s without the main loop vents every chamber (its interrupt), 1 s more resets. */
#define WATCHDOG_MS 1000

/* 16 conversions per value: 4^2 samples buy 2 bits on top of the ADC's 10 (see proto_counts). */
#define OVERSAMPLE 16

/* Timer1 runs at F_CPU / 8: 0.5 us ticks at 16 MHz, so a frame period is exact to 0.5 us. */
#define TIMER_PRESCALE 8UL
#define TICK_HZ (F_CPU / TIMER_PRESCALE)

/*
 * UART with U2X (8 clocks per bit): UBRR = F_CPU / (8 BAUD) - 1, rounded.
 * At 16 MHz, 115200 comes out as 117647 baud (+2.1 %), as on the Arduino core and
 * on the Uno's USB bridge (an ATmega16U2 on the same 16 MHz, so both ends agree);
 * 1000000 is exact.
 */
#define UART_UBRR ((F_CPU + 4UL * BAUD) / (8UL * BAUD) - 1UL)
#define UART_BAUD_REAL (F_CPU / (8UL * (UART_UBRR + 1UL)))
#define UART_BYTES_PER_S (UART_BAUD_REAL / 10UL) /* 8N1: start + 8 data + stop */

/*
 * The longest data line: "$D," seq(10) "," t_us(10) then 6 x ",dddd" and "*HH\n".
 * Lines at the start of a run are shorter (seq and t_us have few digits); a rate
 * must fit the longest one, or frames are lost once the counters grow.
 */
#define LINE_MAX_BYTES (3U + 10U + 1U + 10U + N_CHANNELS * 5U + 4U)

/*
 * Highest RATE accepted, Hz: what the UART carries with the longest line (202 Hz
 * at 115200), and never above ADC_RATE_MAX_HZ.  A frame's 96 conversions at the
 * fastest ADC clock (1 MHz) with their interrupts take 1.6 ms, so frames are lost
 * from about 620 Hz whatever the baud (tests/benchmarks/bench_firmware.py); 500
 * keeps a fifth of the period for formatting and the UART.
 */
#ifndef ADC_RATE_MAX_HZ
#define ADC_RATE_MAX_HZ 500UL
#endif
#define UART_RATE_MAX_HZ (UART_BYTES_PER_S / LINE_MAX_BYTES)
#ifndef RATE_MAX_HZ
#define RATE_MAX_HZ (UART_RATE_MAX_HZ < ADC_RATE_MAX_HZ ? UART_RATE_MAX_HZ : ADC_RATE_MAX_HZ)
#endif
#define RATE_MIN_HZ 1UL
#define RATE_DEFAULT_MHZ 200000UL /* 200 Hz at power-up, the reference protocol's rate */

/* Buffers.  Power-of-two ring sizes so uint8_t indices wrap by themselves. */
#define CMD_MAX 64    /* one command line, '\n' excluded, plus NUL */
#define RX_RING 64    /* host commands are a few bytes each */
#define TX_RING 256   /* four longest lines: a reply can queue behind frames without a drop */

/* Counters start here (a build for testing the 32-bit wrap sets them near 2^32). */
#ifndef SEQ_START
#define SEQ_START 0UL
#endif
#ifndef T_US_START
#define T_US_START 0UL
#endif

#endif
