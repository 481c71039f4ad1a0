# Test helpers shared by every tests/<area>/CMakeLists.txt.
#
# hd_add_unity_test(NAME <name> SOURCES <files...> [LIBS <targets...>] [LABELS <labels...>])
#   Builds one Unity-style test executable and registers it with CTest.  The
#   harness is the project's own (tests/harness) unless HD_UNITY_DIR points at
#   an upstream Unity checkout, in which case the same test files build
#   against that instead.
#   Besides the test <name> (every RUN_TEST of the executable), each RUN_TEST
#   in SOURCES becomes a test <name>.<case> that runs `<name> -n <case>`; they
#   belong to the CTest configuration "case", so a plain `ctest` does not run
#   them and `ctest -C case -R '^<name>\.<case>$'` runs one (docs/reference/testing.md).

if(HD_UNITY_DIR)
  add_library(hd_unity STATIC ${HD_UNITY_DIR}/src/unity.c)
  target_include_directories(hd_unity PUBLIC ${HD_UNITY_DIR}/src)
  target_compile_definitions(hd_unity PUBLIC UNITY_INCLUDE_DOUBLE UNITY_SUPPORT_64
                             UNITY_USE_COMMAND_LINE_ARGS)
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
  foreach(src ${T_SOURCES})
    get_filename_component(src_path ${src} ABSOLUTE)
    set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${src_path})
    file(STRINGS ${src_path} runs REGEX "^[ \t]*RUN_TEST\\([A-Za-z0-9_]+\\)")
    foreach(run ${runs})
      string(REGEX REPLACE "^[ \t]*RUN_TEST\\(([A-Za-z0-9_]+)\\).*" "\\1" case ${run})
      add_test(NAME ${T_NAME}.${case} CONFIGURATIONS case COMMAND ${T_NAME} -n ${case})
      set_tests_properties(${T_NAME}.${case} PROPERTIES TIMEOUT ${T_TIMEOUT}
                           FAIL_REGULAR_EXPRESSION ":FAIL")
      if(T_LABELS)
        set_tests_properties(${T_NAME}.${case} PROPERTIES LABELS "${T_LABELS}")
      endif()
    endforeach()
  endforeach()
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
