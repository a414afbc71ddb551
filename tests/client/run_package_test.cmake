# Installs the client component of BUILD_DIR into WORK_DIR/prefix and builds DOWNSTREAM_SOURCE
# against it with find_package(bgkmap).
file(REMOVE_RECURSE "${WORK_DIR}")
set(prefix "${WORK_DIR}/prefix")

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "failed (${code}): ${ARGN}\n${out}\n${err}")
  endif()
endfunction()

run(${CMAKE_COMMAND} --install "${BUILD_DIR}" --component client --prefix "${prefix}")
run(${CMAKE_COMMAND} -S "${DOWNSTREAM_SOURCE}" -B "${WORK_DIR}/build" -G "${GENERATOR}"
    -DCMAKE_BUILD_TYPE=Release "-DCMAKE_PREFIX_PATH=${prefix}")
run(${CMAKE_COMMAND} --build "${WORK_DIR}/build")
# Nothing listens on port 1: the client must report UNAVAILABLE, not crash.
run("${WORK_DIR}/build/robot_app" "127.0.0.1:1")
