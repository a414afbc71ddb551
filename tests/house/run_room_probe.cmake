# Builds the room probe TARGET in BUILD_DIR. EXPECT=compile: it must build. EXPECT=fail: it must
# fail, and for the reason it was written for: the compiler did not find HEADER (GCC: "HEADER:
# No such file or directory", clang: "'HEADER' file not found"); any other failure fails the test.
execute_process(COMMAND "${CMAKE_COMMAND}" --build "${BUILD_DIR}" --target "${TARGET}"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
if(EXPECT STREQUAL "compile")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${TARGET} must compile (the room may include ${HEADER}):\n${out}")
  endif()
  message(STATUS "${TARGET} compiles: the room may include ${HEADER}")
  return()
endif()
if(rc EQUAL 0)
  message(FATAL_ERROR "${TARGET} compiled: the room sees ${HEADER}, a room it may not touch")
endif()
string(FIND "${out}" "${HEADER}: No such file or directory" gcc_at)
string(FIND "${out}" "'${HEADER}' file not found" clang_at)
if(gcc_at EQUAL -1 AND clang_at EQUAL -1)
  message(FATAL_ERROR "${TARGET} failed, but not for want of ${HEADER}:\n${out}")
endif()
message(STATUS "${TARGET} does not compile: the room cannot see ${HEADER}")
