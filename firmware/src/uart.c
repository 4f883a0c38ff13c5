/*
 * USART0 with a receive and a transmit ring, both served by interrupts.
 *
 * Sizes (config.h): the transmit ring holds four of the longest data lines, so
 * a command's reply queues behind the frames in flight and the main loop never
 * waits on the line at the highest rate; the receive ring holds a command line
 * the main loop has not read yet (commands are a few bytes, seconds apart).
 * Single producer, single consumer per ring: 8-bit indices are read and
 * written atomically on the AVR, so no interrupt locking is needed.
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>

#include "config.h"
#include "events.h"
#include "uart.h"

#if (RX_RING & (RX_RING - 1)) || RX_RING > 256 || (TX_RING & (TX_RING - 1)) || TX_RING > 256
#error "ring sizes must be powers of two up to 256"
#endif
#if UART_BAUD_REAL * 100UL > BAUD * 103UL || UART_BAUD_REAL * 100UL < BAUD * 97UL
#error "BAUD cannot be made within 3 % from F_CPU"
#endif

#define RX_MASK ((uint8_t)(RX_RING - 1))
#define TX_MASK ((uint8_t)(TX_RING - 1))

static char rx_buf[RX_RING];
static volatile uint8_t rx_head; /* written by the RX interrupt */
static volatile uint8_t rx_tail; /* written by the main loop */

static char tx_buf[TX_RING];
static volatile uint8_t tx_head; /* written by the main loop */
static volatile uint8_t tx_tail; /* written by the UDRE interrupt */

void uart_init(void)
{
    UCSR0A = _BV(U2X0); /* before UBRR0: 8 clocks per bit */
    UBRR0H = (uint8_t)(UART_UBRR >> 8);
    UBRR0L = (uint8_t)UART_UBRR;
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8 data bits, no parity, 1 stop bit */
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

ISR(USART_RX_vect)
{
    char c = (char)UDR0;
    uint8_t head = rx_head;
    uint8_t next = (uint8_t)((head + 1) & RX_MASK);
    if (next == rx_tail)
        return; /* ring full: the byte is lost and its line answered with ERR */
    rx_buf[head] = c;
    rx_head = next;
    event_post(EVENT_RX);
}

ISR(USART_UDRE_vect)
{
    uint8_t tail = tx_tail;
    if (tail == tx_head) {
        UCSR0B &= (uint8_t)~_BV(UDRIE0); /* ring empty: quiet until the next write */
        return;
    }
    UDR0 = (uint8_t)tx_buf[tail];
    tx_tail = (uint8_t)((tail + 1) & TX_MASK);
}

int16_t uart_getc(void)
{
    uint8_t tail = rx_tail;
    if (tail == rx_head)
        return -1;
    char c = rx_buf[tail];
    rx_tail = (uint8_t)((tail + 1) & RX_MASK);
    return (uint8_t)c;
}

uint8_t uart_tx_free(void)
{
    return (uint8_t)((tx_tail - tx_head - 1) & TX_MASK);
}

void uart_write(const char *s, uint8_t n)
{
    uint8_t head = tx_head;
    while (n--) {
        tx_buf[head] = *s++;
        head = (uint8_t)((head + 1) & TX_MASK);
    }
    tx_head = head;
    /* Not atomic, and need not be: the UDRE interrupt only ever clears UDRIE0, and
     * setting it again after that is what the bytes just queued need. */
    UCSR0B |= _BV(UDRIE0);
}

void uart_write_wait(const char *s)
{
    while (*s) {
        cli();
        if (!uart_tx_free()) {
            /* The UDRE interrupt frees a byte and wakes us; sei's one-instruction delay
             * makes the sleep safe against it firing in between. */
            sleep_enable();
            sei();
            sleep_cpu();
            sleep_disable();
            continue;
        }
        sei();
        uart_write(s++, 1);
    }
}
