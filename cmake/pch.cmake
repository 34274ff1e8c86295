# Precompiled headers: build time only, no change to the code a build makes.
#
# Most of the time spent compiling the glue (the server library, the client library, the CLI)
# goes to parsing the same headers again in every file: gRPC's, the generated service and
# message headers, and Eigen's through fulcrum/world.h (a CLI file took 7 s with gcc -O2, 1.5 s
# with them precompiled). Each of those targets parses them once. The engine and the scene
# builders compile without: their files are light, and what the determinism checks compare is
# their code. FULCRUM_PCH=OFF turns it off.
#
# Tried and left out (2026-11-29): the tests, which are one file per executable and would share
# one precompiled header per family (REUSE_FROM) -- at gcc -O2 their time is code generation, and
# they saved 7 %; and fulcrum_convert -- through a precompiled header, gcc 12 reports its
# -Warray-bounds false positive on std::string's operator+ (inside the standard headers, which it
# otherwise keeps quiet as system headers), an error with FULCRUM_WERROR.
option(FULCRUM_PCH "Precompile the heavy headers of the server, client and CLI (build time only)"
       ON)

# TARGET's files all start with these headers, parsed once for the target.
function(fulcrum_precompile target)
  if(FULCRUM_PCH)
    target_precompile_headers(${target} PRIVATE <algorithm> <chrono> <cmath> <cstdint> <map>
                              <memory> <mutex> <string> <thread> <vector> ${ARGN})
  endif()
endfunction()
