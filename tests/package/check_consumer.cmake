# Configures, builds and runs tests/package/consumer against stratum.
#   cmake -DSOURCE_DIR=... -DWORK_DIR=... -DMODE=install|subdirectory [-DCXX=...] -P check_consumer.cmake
# MODE=install: installs stratum into WORK_DIR/prefix and uses find_package(stratum CONFIG).
# MODE=subdirectory: the consumer pulls stratum in with add_subdirectory.
function(run)
  execute_process(COMMAND ${ARGV} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "command failed (${rc}): ${ARGV}\n${out}\n${err}")
  endif()
endfunction()

file(REMOVE_RECURSE ${WORK_DIR})
set(compiler "")
if(CXX)
  set(compiler -DCMAKE_CXX_COMPILER=${CXX})
endif()
set(consumer_args -S ${SOURCE_DIR}/tests/package/consumer -B ${WORK_DIR}/consumer ${compiler})
if(MODE STREQUAL "install")
  run(${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/stratum ${compiler} -DSTRATUM_BUILD_TESTS=OFF
      -DSTRATUM_BUILD_BENCHMARKS=OFF -DSTRATUM_BUILD_EXAMPLES=OFF)
  run(${CMAKE_COMMAND} --install ${WORK_DIR}/stratum --prefix ${WORK_DIR}/prefix)
  run(${CMAKE_COMMAND} ${consumer_args} -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix)
elseif(MODE STREQUAL "subdirectory")
  run(${CMAKE_COMMAND} ${consumer_args} -DSTRATUM_SOURCE_DIR=${SOURCE_DIR})
else()
  message(FATAL_ERROR "MODE must be install or subdirectory, not '${MODE}'")
endif()
run(${CMAKE_COMMAND} --build ${WORK_DIR}/consumer)
run(${WORK_DIR}/consumer/consumer)
message(STATUS "consumer (${MODE}) built and ran")
