# `fulcrum export --builtin NAME` must produce a scene file that simulates to the same state
# hash as the builtin itself: the JSON export loses no bits.
#
#   cmake -DCLI=path/to/fulcrum -DNAME=builtin -DTICKS=N -DWORK_DIR=dir -P export_roundtrip.cmake
set(file "${WORK_DIR}/export_${NAME}.json")
execute_process(COMMAND "${CLI}" export --builtin ${NAME}
  RESULT_VARIABLE rc OUTPUT_FILE "${file}" ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "export --builtin ${NAME} failed (${rc}): ${err}")
endif()

function(sim_hash out_var)
  execute_process(COMMAND "${CLI}" sim ${ARGN} --ticks ${TICKS} --json
    RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "sim ${ARGN} failed (${rc}): ${err}")
  endif()
  if(NOT out MATCHES "\"stateHash\":\"([0-9a-f]+)\"")
    message(FATAL_ERROR "no stateHash in: ${out}")
  endif()
  set(${out_var} "${CMAKE_MATCH_1}" PARENT_SCOPE)
endfunction()

sim_hash(builtin_hash --builtin ${NAME})
sim_hash(file_hash --scene "${file}")
if(NOT builtin_hash STREQUAL file_hash)
  message(FATAL_ERROR "builtin ${NAME}: hash ${builtin_hash}, exported file: ${file_hash}")
endif()
message(STATUS "${NAME}: ${builtin_hash} after ${TICKS} ticks, both ways")
