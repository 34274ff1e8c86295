# Removes the *_pb2_grpc.py files grpc_python_plugin writes for protos without a service (they
# import nothing and define nothing). usage: cmake -DDIR=<fulcrum/v1 dir> -P remove_empty_grpc.cmake
file(GLOB stubs ${DIR}/*_pb2_grpc.py)
foreach(stub ${stubs})
  file(READ ${stub} text)
  if(NOT text MATCHES "class ")
    file(REMOVE ${stub})
  endif()
endforeach()
