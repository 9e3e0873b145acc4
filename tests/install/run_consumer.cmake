# Installs subslam from SUBSLAM_BUILD_DIR into WORK_DIR/prefix, configures and builds the
# consumer project in SOURCE_DIR against it, simulates a short data set with SUBSLAM_APP
# and runs the consumer on it. Run by CTest: cmake -D… -P run_consumer.cmake.
foreach(var SUBSLAM_BUILD_DIR SOURCE_DIR WORK_DIR SUBSLAM_APP CXX_COMPILER)
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
run(install ${CMAKE_COMMAND} --install "${SUBSLAM_BUILD_DIR}" --prefix "${WORK_DIR}/prefix")
set(configure_args -S "${SOURCE_DIR}" -B "${WORK_DIR}/build" -DCMAKE_BUILD_TYPE=Release
    "-DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix" "-DCMAKE_CXX_COMPILER=${CXX_COMPILER}")
if(CXX_LAUNCHER)
  list(APPEND configure_args "-DCMAKE_CXX_COMPILER_LAUNCHER=${CXX_LAUNCHER}")
endif()
run(configure ${CMAKE_COMMAND} ${configure_args})
run(build ${CMAKE_COMMAND} --build "${WORK_DIR}/build")
run(simulate "${SUBSLAM_APP}" simulate --scenario hybrid-120m --seed 1 --duration 60 --out "${WORK_DIR}/data")
run(consumer "${WORK_DIR}/build/consumer" "${WORK_DIR}/data")
message(STATUS "${last_output}")
