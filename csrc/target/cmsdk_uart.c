/* The CMSDK APB UART of the MPS2 boards (cmsdk_uart.h). */
#include "cmsdk_uart.h"

#define UART_DATA(b) (*(volatile uint32_t *)((b) + 0x00u))    /* received / to send byte */
#define UART_STATE(b) (*(volatile uint32_t *)((b) + 0x04u))   /* bit 0 TX buffer full, bit 1 RX buffer full */
#define UART_CTRL(b) (*(volatile uint32_t *)((b) + 0x08u))    /* bit 0 TX enable, bit 1 RX enable */
#define UART_BAUDDIV(b) (*(volatile uint32_t *)((b) + 0x10u)) /* pclk / baud, >= 16 */
#define UART_TX_FULL 0x1u
#define UART_RX_FULL 0x2u

void p2d_uart_init(uint32_t base, uint32_t pclk_Hz, uint32_t baud)
{
    UART_BAUDDIV(base) = pclk_Hz / baud;
    UART_CTRL(base) = 0x3u;
}

uint32_t p2d_uart_receive(uint32_t base, uint8_t *bytes, uint32_t capacity)
{
    uint32_t n = 0u;
    while (n < capacity && (UART_STATE(base) & UART_RX_FULL) != 0u) {
        bytes[n++] = (uint8_t)UART_DATA(base);
    }
    return n;
}

uint32_t p2d_uart_send(uint32_t base, const uint8_t *bytes, uint32_t n)
{
    uint32_t k = 0u;
    while (k < n && (UART_STATE(base) & UART_TX_FULL) == 0u) {
        UART_DATA(base) = bytes[k++];
    }
    return k;
}

void p2d_uart_put(uint32_t base, uint8_t byte)
{
    while ((UART_STATE(base) & UART_TX_FULL) != 0u) {
    }
    UART_DATA(base) = byte;
}
