# cmake -DSUBSLAM=<path to the subslam tool> -DDOC=<docs/cli.md> -P CheckCliReference.cmake
# Fails when docs/cli.md is not the tool's own `subslam cli-reference` output.
execute_process(COMMAND "${SUBSLAM}" cli-reference OUTPUT_VARIABLE generated
                RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "`${SUBSLAM} cli-reference` failed (exit status ${status})")
endif()
file(READ "${DOC}" committed)
if(NOT generated STREQUAL committed)
  message(FATAL_ERROR "${DOC} is not the tool's current reference: run "
                      "scripts/update_cli_doc.sh and commit the result")
endif()
