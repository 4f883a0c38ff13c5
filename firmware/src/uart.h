/* USART0, interrupt driven, 8N1 at BAUD (config.h): ring buffers both ways. */
#ifndef LABCLI_UART_H
#define LABCLI_UART_H

#include <stdint.h>

void uart_init(void);

/* The next received byte, or -1 when none is waiting. */
int16_t uart_getc(void);

/* Bytes the transmit ring can take now. */
uint8_t uart_tx_free(void);

/* Queue n bytes; the caller has checked uart_tx_free() (a data line is sent whole or not at all). */
void uart_write(const char *s, uint8_t n);

/* Queue a NUL-terminated line, sleeping while the ring is full (replies and log lines are never dropped). */
void uart_write_wait(const char *s);

#endif
