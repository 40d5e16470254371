# CMake toolchain file: Cortex-M0 (ARMv6-M, no FPU, no 32x32->64 multiply), bare metal, Debian's arm-none-eabi-gcc
# with newlib; the board of the emulated target programs is P2D_BOARD (microbit: QEMU -M microbit).
#
#   cmake -S csrc -B build-m0 -DCMAKE_TOOLCHAIN_FILE="$PWD/csrc/cmake/arm-none-eabi-cortex-m0.cmake"
#   cmake --build build-m0
#
# The fixed-point speed controllers (pmsm2dof/speed_fixed.h) are what this core runs; the float32
# code builds too, with software floating point (-mfloat-abi=soft, newlib's libgcc routines).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_AR arm-none-eabi-ar)
set(CMAKE_RANLIB arm-none-eabi-ranlib)
set(CMAKE_OBJCOPY arm-none-eabi-objcopy)
set(CMAKE_SIZE arm-none-eabi-size)

set(P2D_CORTEX_FLAGS "-mcpu=cortex-m0 -mthumb -mfloat-abi=soft")
set(CMAKE_C_FLAGS_INIT "${P2D_CORTEX_FLAGS} -O2 -ffp-contract=off -ffunction-sections -fdata-sections")
set(CMAKE_EXE_LINKER_FLAGS_INIT "${P2D_CORTEX_FLAGS} --specs=nano.specs -nostartfiles -Wl,--gc-sections")
set(P2D_BOARD microbit CACHE STRING "board of the target programs (csrc/target)")

# no operating system to run a test executable on: check the compiler with a static library
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
