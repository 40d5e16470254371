/*
 * The UARTs of the Arm MPS2 boards (AN385, AN386): CMSDK APB UARTs (Arm
 * Cortex-M System Design Kit Technical Reference Manual, DDI0479, "UART"),
 * UART0 at 0x40004000, 8N1, a one-byte buffer each way and no FIFO. Polled:
 * nothing here waits (the byte link of the firmware's XCP slave polls it from
 * the background loop). On QEMU -M mps2-an386, UART0 is the first -serial
 * (a pty, a TCP port, stdio); QEMU hands over the next received byte once the
 * last one was read, so no byte is lost however long the firmware is away.
 */
#ifndef P2D_CMSDK_UART_H
#define P2D_CMSDK_UART_H

#include <stdint.h>

/* Base address of UART0 of the MPS2 boards. */
#define P2D_UART0 0x40004000u

/* Enable receiver and transmitter at baud [bit/s] of the peripheral clock pclk_Hz (the board's 25 MHz). */
void p2d_uart_init(uint32_t base, uint32_t pclk_Hz, uint32_t baud);

/* The received bytes waiting in the UART (at most one: the one-byte buffer) into bytes; their number. */
uint32_t p2d_uart_receive(uint32_t base, uint8_t *bytes, uint32_t capacity);

/* Write bytes while the transmitter takes them (its buffer empty); returns how many it took. */
uint32_t p2d_uart_send(uint32_t base, const uint8_t *bytes, uint32_t n);

/* Write a byte, waiting for the transmitter (diagnostics outside the control loop). */
void p2d_uart_put(uint32_t base, uint8_t byte);

#endif /* P2D_CMSDK_UART_H */
