/*
 * Minimal startup for a Cortex-M (M4F, M3, M0): vector table, reset handler
 * (FPU on where the core has one, .data copied from flash, .bss cleared, main
 * called) and weak default handlers. Handlers are overridden by defining a
 * function of the same name, e.g. SysTick_Handler. Word 0 of the table
 * (initial stack pointer) is placed by the linker script. On an Armv6-M core
 * (M0) the entries of MemManage, BusFault, UsageFault and DebugMon are
 * reserved and never taken.
 *
 * Register addresses: Armv7-M Architecture Reference Manual (DDI 0403),
 * B3.2 System Control Space; CPACR at 0xE000ED88, CP10/CP11 in bits 20-23.
 */
#include <stdint.h>

/* defined in the linker script */
extern uint32_t __data_start;
extern uint32_t __data_end;
extern uint32_t __data_load;
extern uint32_t __bss_start;
extern uint32_t __bss_end;

int main(void);

typedef void (*p2d_vector_t)(void);

void Reset_Handler(void);
void p2d_default_handler(void);
void NMI_Handler(void) __attribute__((weak, alias("p2d_default_handler")));
void HardFault_Handler(void) __attribute__((weak, alias("p2d_default_handler")));
void MemManage_Handler(void) __attribute__((weak, alias("p2d_default_handler")));
void BusFault_Handler(void) __attribute__((weak, alias("p2d_default_handler")));
void UsageFault_Handler(void) __attribute__((weak, alias("p2d_default_handler")));
void SVC_Handler(void) __attribute__((weak, alias("p2d_default_handler")));
void DebugMon_Handler(void) __attribute__((weak, alias("p2d_default_handler")));
void PendSV_Handler(void) __attribute__((weak, alias("p2d_default_handler")));
void SysTick_Handler(void) __attribute__((weak, alias("p2d_default_handler")));

/* exception vectors 1..15 (Armv7-M ARM, B1.5.3); device interrupts would follow */
__attribute__((section(".isr_vector"), used)) static const p2d_vector_t p2d_vectors[15] = {
    Reset_Handler,
    NMI_Handler,
    HardFault_Handler,
    MemManage_Handler,
    BusFault_Handler,
    UsageFault_Handler,
    0,
    0,
    0,
    0,
    SVC_Handler,
    DebugMon_Handler,
    0,
    PendSV_Handler,
    SysTick_Handler,
};

#define P2D_SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)

void Reset_Handler(void)
{
    const uint32_t *src = &__data_load;
    uint32_t *dst;

#if defined(__ARM_FP)
    /* full access to CP10 and CP11, the FPU, before any floating-point instruction */
    P2D_SCB_CPACR |= 0xFu << 20;
    __asm__ volatile("dsb\n\tisb" ::: "memory");
#endif

    for (dst = &__data_start; dst < &__data_end; ++dst) {
        *dst = *src++;
    }
    for (dst = &__bss_start; dst < &__bss_end; ++dst) {
        *dst = 0u;
    }
    (void)main();
    for (;;) {
    }
}

void p2d_default_handler(void)
{
    for (;;) {
    }
}
