# Test helpers shared by every tests/<area>/CMakeLists.txt.
#
# hd_add_unity_test(NAME <name> SOURCES <files...> [LIBS <targets...>] [LABELS <labels...>])
#   Builds one Unity-style test executable and registers it with CTest.  The
#   harness is the project's own (tests/harness) unless HD_UNITY_DIR points at
#   an upstream Unity checkout, in which case the same test files build
#   against that instead.

if(HD_UNITY_DIR)
  add_library(hd_unity STATIC ${HD_UNITY_DIR}/src/unity.c)
  target_include_directories(hd_unity PUBLIC ${HD_UNITY_DIR}/src)
  target_compile_definitions(hd_unity PUBLIC UNITY_INCLUDE_DOUBLE UNITY_SUPPORT_64)
  # Upstream Unity is not ours to keep warning-free.
  target_compile_options(hd_unity PRIVATE -w)
else()
  add_library(hd_unity STATIC ${PROJECT_SOURCE_DIR}/tests/harness/unity.c)
  target_include_directories(hd_unity PUBLIC ${PROJECT_SOURCE_DIR}/tests/harness)
endif()
target_link_libraries(hd_unity PUBLIC m)

function(hd_add_unity_test)
  cmake_parse_arguments(T "" "NAME;TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${T_NAME} ${T_SOURCES})
  target_link_libraries(${T_NAME} PRIVATE hd_unity ${T_LIBS} m)
  add_test(NAME ${T_NAME} COMMAND ${T_NAME})
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 300)
  endif()
  set_tests_properties(${T_NAME} PROPERTIES TIMEOUT ${T_TIMEOUT}
                       FAIL_REGULAR_EXPRESSION ":FAIL")
  if(T_LABELS)
    set_tests_properties(${T_NAME} PROPERTIES LABELS "${T_LABELS}")
  endif()
endfunction()

# hd_add_python_test(NAME <name> ARGS <pytest args...>)
#   Runs pytest from the project's virtual environment (tools/setup makes it).
set(HD_PYTHON ${PROJECT_SOURCE_DIR}/.venv/bin/python CACHE FILEPATH
    "Python interpreter of the project's virtual environment")
function(hd_add_python_test)
  cmake_parse_arguments(T "" "NAME;TIMEOUT" "ARGS;LABELS" ${ARGN})
  add_test(NAME ${T_NAME}
           COMMAND ${HD_PYTHON} -m pytest -q -p no:cacheprovider ${T_ARGS}
           WORKING_DIRECTORY ${PROJECT_SOURCE_DIR})
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 600)
  endif()
  set_tests_properties(${T_NAME} PROPERTIES TIMEOUT ${T_TIMEOUT}
                       ENVIRONMENT "HD_BUILD_DIR=${PROJECT_BINARY_DIR}")
  if(T_LABELS)
    set_tests_properties(${T_NAME} PROPERTIES LABELS "${T_LABELS}")
  endif()
endfunction()
