# Runs one fulcrum CLI invocation and checks its exit code and output (ctest's
# PASS_REGULAR_EXPRESSION alone ignores the exit code).
#
#   cmake -DCLI=path/to/fulcrum -DARGS="sim|--ticks|10" -DEXPECT_RC=0
#         [-DSTDOUT_REGEX=...] [-DSTDERR_REGEX=...] -P run_cli.cmake
#
# ARGS separates words with "|" because ";" would be split by ctest.
string(REPLACE "|" ";" args "${ARGS}")
execute_process(COMMAND "${CLI}" ${args}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
set(report "command: ${CLI} ${args}\nexit code: ${rc}\nstdout:\n${out}\nstderr:\n${err}")
if(NOT "${rc}" STREQUAL "${EXPECT_RC}")
  message(FATAL_ERROR "expected exit code ${EXPECT_RC}\n${report}")
endif()
if(DEFINED STDOUT_REGEX AND NOT out MATCHES "${STDOUT_REGEX}")
  message(FATAL_ERROR "stdout does not match '${STDOUT_REGEX}'\n${report}")
endif()
if(DEFINED STDERR_REGEX AND NOT err MATCHES "${STDERR_REGEX}")
  message(FATAL_ERROR "stderr does not match '${STDERR_REGEX}'\n${report}")
endif()
