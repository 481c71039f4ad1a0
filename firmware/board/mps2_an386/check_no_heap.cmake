# cmake -DNM=arm-none-eabi-nm -DELF=image.elf -P check_no_heap.cmake
# Fails if the image defines or references an allocator.
execute_process(COMMAND ${NM} ${ELF} OUTPUT_VARIABLE syms RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "no-heap check: ${NM} failed on ${ELF}")
endif()
foreach(sym malloc _malloc_r calloc realloc free _free_r _sbrk _sbrk_r sbrk)
  if(syms MATCHES "[ \t][A-Za-z][ \t]${sym}\n")
    message(FATAL_ERROR "no-heap check: ${ELF} contains ${sym}")
  endif()
endforeach()
message(STATUS "no-heap check: ${ELF}: no malloc/free/_sbrk")
