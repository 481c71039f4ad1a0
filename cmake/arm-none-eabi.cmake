# Toolchain file: Cortex-M4F (STM32F4/G4 class joint MCUs) with Debian's
# gcc-arm-none-eabi.  Used by the `cortex-m4` preset (CMakePresets.json):
#   cmake --preset cortex-m4 && cmake --build --preset cortex-m4
# tools/setup installs the compiler (and qemu-system-arm to run the image).
# Second inclusion, as the make-rules override (see the end of this file):
# only drop the PIC flags that CMake's compiler modules have just set.
if(CMAKE_C_COMPILER_LOADED)
  set(CMAKE_C_COMPILE_OPTIONS_PIC "")
  set(CMAKE_C_COMPILE_OPTIONS_PIE "")
  set(CMAKE_C_LINK_OPTIONS_PIE "")
  return()
endif()

set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
find_program(HD_ARM_OBJCOPY arm-none-eabi-objcopy)
find_program(HD_ARM_SIZE arm-none-eabi-size)
find_program(HD_ARM_NM arm-none-eabi-nm)

# No hosted libc/crt: try_compile must not try to link an executable.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

# The MCU flags, plus what the budget report needs:
#  -ffunction-sections/-fdata-sections: unused code is dropped at link time;
#  -fstack-usage / -fcallgraph-info=su: per-function stack and the call graph
#  (.su / .ci files next to the objects) for the worst-case stack analysis.
set(HD_M4_FLAGS "-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard")
set(CMAKE_C_FLAGS_INIT
    "${HD_M4_FLAGS} -ffunction-sections -fdata-sections -fstack-usage -fcallgraph-info=su")
set(CMAKE_ASM_FLAGS_INIT "${HD_M4_FLAGS}")
# No crt0, no libc, no libm: the board provides startup and the few string
# functions the compiler may call; images link libgcc (64-bit division)
# explicitly.
set(CMAKE_EXE_LINKER_FLAGS_INIT "-nostartfiles -nostdlib -Wl,--gc-sections")

set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)

# The top-level CMakeLists turns on POSITION_INDEPENDENT_CODE for the host's
# shared libraries.  A bare-metal image is linked at fixed addresses: -fPIC
# would add GOT indirections to every global access.  This file is loaded
# again as the "make rules override", after CMake's compiler modules set
# the PIC flags, and empties them (the block at the top).
set(CMAKE_USER_MAKE_RULES_OVERRIDE ${CMAKE_CURRENT_LIST_FILE})
