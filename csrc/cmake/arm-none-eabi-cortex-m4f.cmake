# CMake toolchain file: Cortex-M4F (ARMv7E-M, single-precision FPU), bare metal,
# Debian's arm-none-eabi-gcc with newlib.
#
#   cmake -S csrc -B build-m4f -DCMAKE_TOOLCHAIN_FILE="$PWD/csrc/cmake/arm-none-eabi-cortex-m4f.cmake"
#   cmake --build build-m4f
#
# (from the repository root; CMake reads a relative toolchain path against the
# build folder and the source folder, not the current one: give it absolute)
#
# -ffp-contract=off keeps every a*b+c as a rounded multiply and a rounded add,
# as on the host (x86-64 has no FMA without -mfma): the float32 results on the
# MCU are then equal to the bit to those of the simulation. Removing it lets GCC
# fuse into vfma.f32 (fewer instructions, results differ in the last bits).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_AR arm-none-eabi-ar)
set(CMAKE_RANLIB arm-none-eabi-ranlib)
set(CMAKE_OBJCOPY arm-none-eabi-objcopy)
set(CMAKE_SIZE arm-none-eabi-size)

set(P2D_CORTEX_M4F_FLAGS "-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard")
set(CMAKE_C_FLAGS_INIT "${P2D_CORTEX_M4F_FLAGS} -O2 -ffp-contract=off -ffunction-sections -fdata-sections")
# newlib-nano's libc and libm; the startup code and the linker script come from the application
set(CMAKE_EXE_LINKER_FLAGS_INIT "${P2D_CORTEX_M4F_FLAGS} --specs=nano.specs -nostartfiles -Wl,--gc-sections")

# no operating system to run a test executable on: check the compiler with a static library
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
