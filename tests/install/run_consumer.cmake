# Installs subslam from SUBSLAM_BUILD_DIR into WORK_DIR/prefix, configures and builds the
# consumer project in SOURCE_DIR against it, simulates a short data set with SUBSLAM_APP
# and runs the consumer and the navigation-loop example on it; then, on a machine with
# AVX2, the same consumer built for AVX2 (-march=haswell) (another Eigen alignment than the library's unless the layout is pinned, see
# cmake/SubslamHelpers.cmake). Run by CTest: cmake -D… -P run_consumer.cmake.
foreach(var SUBSLAM_BUILD_DIR SOURCE_DIR WORK_DIR SUBSLAM_APP CXX_COMPILER GENERATOR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "run_consumer.cmake: ${var} not set")
  endif()
endforeach()

function(run step)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE result OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT result EQUAL 0)
    message(FATAL_ERROR "${step} failed (${result}):\n${out}\n${err}")
  endif()
  set(last_output "${out}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
# `cmake --install` rewrites the build tree's install_manifest.txt: keep the user's.
set(manifest "${SUBSLAM_BUILD_DIR}/install_manifest.txt")
if(EXISTS "${manifest}")
  file(COPY_FILE "${manifest}" "${WORK_DIR}/install_manifest.saved")
endif()
run(install ${CMAKE_COMMAND} --install "${SUBSLAM_BUILD_DIR}" --prefix "${WORK_DIR}/prefix")
if(EXISTS "${WORK_DIR}/install_manifest.saved")
  file(COPY_FILE "${WORK_DIR}/install_manifest.saved" "${manifest}")
else()
  file(REMOVE "${manifest}")
endif()
# The consumer is configured like the library: same generator, compiler, flags and
# dependency search path (the test prefix first).
# The prefix path is a list: it goes through an initial-cache file, where its ';' stay
# inside one value (PARENT_PREFIX_PATH comes with '|' for ';', see tests/CMakeLists.txt).
string(REPLACE "|" ";" parent_prefix_path "${PARENT_PREFIX_PATH}")
file(WRITE "${WORK_DIR}/init.cmake" "set(CMAKE_PREFIX_PATH \"${WORK_DIR}/prefix;${parent_prefix_path}\" CACHE STRING \"\")\n")
set(configure_args -S "${SOURCE_DIR}" -B "${WORK_DIR}/build" -G "${GENERATOR}" -C "${WORK_DIR}/init.cmake"
    -DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_COMPILER=${CXX_COMPILER}" "-DCMAKE_CXX_FLAGS=${CXX_FLAGS}"
    -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF)
if(MAKE_PROGRAM)
  list(APPEND configure_args "-DCMAKE_MAKE_PROGRAM=${MAKE_PROGRAM}")
endif()
if(CXX_LAUNCHER)
  list(APPEND configure_args "-DCMAKE_CXX_COMPILER_LAUNCHER=${CXX_LAUNCHER}")
endif()
run(configure ${CMAKE_COMMAND} ${configure_args})
run(build ${CMAKE_COMMAND} --build "${WORK_DIR}/build")
run(simulate "${SUBSLAM_APP}" simulate --scenario hybrid-120m --seed 1 --duration 60 --out "${WORK_DIR}/data")
run(consumer "${WORK_DIR}/build/consumer" "${WORK_DIR}/data")
message(STATUS "${last_output}")
run(navigation_loop "${WORK_DIR}/build/navigation_loop" "${WORK_DIR}/data")
message(STATUS "navigation_loop: ${last_output}")
file(READ /proc/cpuinfo cpuinfo LIMIT 20000)
if(cpuinfo MATCHES " avx2 " AND cpuinfo MATCHES " fma " AND cpuinfo MATCHES " bmi2 ")
  list(FIND configure_args "${WORK_DIR}/build" at)
  list(REMOVE_AT configure_args ${at})
  list(INSERT configure_args ${at} "${WORK_DIR}/build-avx2")
  list(FILTER configure_args EXCLUDE REGEX "^-DCMAKE_CXX_FLAGS=")
  list(APPEND configure_args "-DCMAKE_CXX_FLAGS=${CXX_FLAGS} -march=haswell")  # last -march wins
  run(configure-avx2 ${CMAKE_COMMAND} ${configure_args})
  run(build-avx2 ${CMAKE_COMMAND} --build "${WORK_DIR}/build-avx2")
  run(consumer-avx2 "${WORK_DIR}/build-avx2/consumer" "${WORK_DIR}/data")
  message(STATUS "AVX2 build: ${last_output}")
endif()
# The Python package, when the build has it: importable from the installed prefix alone,
# and running the simulated data set.
if(PYTHON AND PYTHON_PACKAGE_DIR)
  set(site "${WORK_DIR}/prefix/${PYTHON_PACKAGE_DIR}")
  if(NOT EXISTS "${site}/subslam/__init__.py")
    message(FATAL_ERROR "the Python package is not installed in ${site}")
  endif()
  file(WRITE "${WORK_DIR}/use_subslam.py" "import subslam\n"
       "r = subslam.run(dataset='${WORK_DIR}/data', frontend='ekfslam')\n"
       "print(subslam.__file__, len(r.landmarks.ids), 'landmarks')\n")
  run(python ${CMAKE_COMMAND} -E env "PYTHONPATH=${site}" "${PYTHON}" "${WORK_DIR}/use_subslam.py")
  message(STATUS "python: ${last_output}")
endif()
