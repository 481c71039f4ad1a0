# The hdtools wheel (`pip install ./tools`, scikit-build-core sets SKBUILD):
# the C libraries and host executables the tools load, and the source files
# they read at run time (hdtools/paths.py DATA_FILES), installed into the
# package, so that an installed hdsense needs no build tree.  The package
# finds them as hdtools/native.py says.
set(HD_WHEEL_LIBS hdfilter_shared hdcalib_shared hd_emu_shared)
set(HD_WHEEL_EXES hdsim_cli hdsim_campaign hdjoint-host)
foreach(t ${HD_WHEEL_LIBS})
  install(TARGETS ${t} LIBRARY DESTINATION hdtools/lib)
endforeach()
foreach(t ${HD_WHEEL_EXES})
  install(TARGETS ${t} RUNTIME DESTINATION hdtools/bin)
endforeach()
# DATA_FILES of tools/hdtools/paths.py, read from there (one list)
file(READ ${PROJECT_SOURCE_DIR}/tools/hdtools/paths.py HD_PATHS_PY)
string(REGEX MATCH "DATA_FILES = \\(([^)]*)\\)" _ "${HD_PATHS_PY}")
string(REGEX MATCHALL "\"[^\"]+\"" HD_DATA_FILES "${CMAKE_MATCH_1}")
if(NOT HD_DATA_FILES)
  message(FATAL_ERROR "tools/hdtools/paths.py: no DATA_FILES")
endif()
foreach(f ${HD_DATA_FILES})
  string(REPLACE "\"" "" f ${f})
  install(FILES ${PROJECT_SOURCE_DIR}/${f} DESTINATION hdtools/data)
endforeach()
execute_process(COMMAND git -C ${PROJECT_SOURCE_DIR} rev-parse --short=12 HEAD
                OUTPUT_VARIABLE HD_GIT OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
file(WRITE ${PROJECT_BINARY_DIR}/build_info.txt
     "version = ${PROJECT_VERSION}\ngit = ${HD_GIT}\nsource_root = ${PROJECT_SOURCE_DIR}\n")
install(FILES ${PROJECT_BINARY_DIR}/build_info.txt DESTINATION hdtools/data)
