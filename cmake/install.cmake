# What `cmake --install` puts under the prefix (docs/library.md):
#   lib/                  static libraries: engine, scenes, proto, grpc, convert, client
#   include/fulcrum/      the engine's, the scene builders' and the client's public headers;
#                         convert/ (scene loader, snapshots, replays); v1/ (generated protobuf)
#   bin/                  fulcrum-server and the fulcrum command-line tool
#   lib/cmake/Fulcrum/    the CMake package: find_package(Fulcrum) gives Fulcrum::engine ...
#   lib/pkgconfig/        fulcrum-engine.pc, fulcrum-scenes.pc, fulcrum-proto.pc,
#                         fulcrum-convert.pc, fulcrum-client.pc
#   share/fulcrum/scenes/ the scene files of scenes/
# Tests, benchmarks and fuzz targets are not installed. lib/ is GNUInstallDirs' LIBDIR
# (lib/x86_64-linux-gnu under /usr on Debian).
include(CMakePackageConfigHelpers)

set(FULCRUM_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/Fulcrum)

# The libraries, in one export set. fulcrum_grpc (the generated service stubs) is in it because
# the client, a static library, links it; Fulcrum::grpc is also usable on its own.
install(TARGETS fulcrum_engine fulcrum_scenes fulcrum_proto fulcrum_grpc fulcrum_convert
                fulcrum_client
        EXPORT FulcrumTargets)
install(TARGETS fulcrum-server fulcrum)

install(DIRECTORY ${PROJECT_SOURCE_DIR}/engine/include/fulcrum
                  ${PROJECT_SOURCE_DIR}/scenes/builders/include/fulcrum
                  ${PROJECT_SOURCE_DIR}/client/include/fulcrum
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/proto/convert/
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/fulcrum/convert
        FILES_MATCHING PATTERN "*.h")
# The generated headers of fulcrum/v1 (messages and service stubs); agones/ is the server's.
get_target_property(proto_binary_dir fulcrum_proto BINARY_DIR)
install(DIRECTORY ${proto_binary_dir}/gen/fulcrum DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        FILES_MATCHING PATTERN "*.pb.h")
install(DIRECTORY ${PROJECT_SOURCE_DIR}/scenes/ DESTINATION ${CMAKE_INSTALL_DATADIR}/fulcrum/scenes
        FILES_MATCHING PATTERN "*.json" PATTERN builders EXCLUDE)

# The CMake package: FulcrumTargets.cmake (the imported targets, Fulcrum::engine ...),
# FulcrumConfig.cmake (finds what their link interface names first) and its version file.
# 0.x: a new minor version may break the API, so only the same minor version is compatible.
install(EXPORT FulcrumTargets NAMESPACE Fulcrum:: DESTINATION ${FULCRUM_INSTALL_CMAKEDIR})
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/FulcrumConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/cmake/FulcrumConfig.cmake
                              INSTALL_DESTINATION ${FULCRUM_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/cmake/FulcrumConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/cmake/FulcrumConfig.cmake
              ${PROJECT_BINARY_DIR}/cmake/FulcrumConfigVersion.cmake
        DESTINATION ${FULCRUM_INSTALL_CMAKEDIR})

# pkg-config files, one per library that users link. The libraries are static archives, so what
# they link goes in Requires and Libs, not in the .private fields (which only --static reads).
# The paths are relative to the .pc file's own directory (${pcfiledir}): a copy installed with
# `cmake --install --prefix DIR`, or moved, still names its own headers and libraries.
file(RELATIVE_PATH FULCRUM_PC_PREFIX ${CMAKE_INSTALL_FULL_LIBDIR}/pkgconfig
     ${CMAKE_INSTALL_PREFIX})
string(REGEX REPLACE "/$" "" FULCRUM_PC_PREFIX ${FULCRUM_PC_PREFIX})  # "../../" -> "../.."
# The engine's determinism flags, from the target's PUBLIC options (engine/CMakeLists.txt) so that
# the two never disagree.
get_target_property(engine_options fulcrum_engine INTERFACE_COMPILE_OPTIONS)
get_target_property(engine_definitions fulcrum_engine INTERFACE_COMPILE_DEFINITIONS)
list(TRANSFORM engine_definitions PREPEND "-D")
string(JOIN " " FULCRUM_DETERMINISM_CFLAGS ${engine_options} ${engine_definitions})
if(FULCRUM_DETERMINISM_CFLAGS MATCHES "\\$<")
  message(FATAL_ERROR "fulcrum_engine's public options hold a generator expression, which "
                      "fulcrum-engine.pc cannot: ${FULCRUM_DETERMINISM_CFLAGS}")
endif()

function(fulcrum_pkg_config name description requires libs cflags)
  set(PC_NAME ${name})
  set(PC_DESCRIPTION ${description})
  set(PC_REQUIRES ${requires})
  set(PC_LIBS ${libs})
  set(PC_CFLAGS ${cflags})
  configure_file(${CMAKE_CURRENT_FUNCTION_LIST_DIR}/fulcrum.pc.in
                 ${PROJECT_BINARY_DIR}/pkgconfig/${name}.pc @ONLY)
  install(FILES ${PROJECT_BINARY_DIR}/pkgconfig/${name}.pc
          DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
endfunction()

fulcrum_pkg_config(fulcrum-engine "Fulcrum: deterministic 2D physics engine" "eigen3"
                   "-lfulcrum_engine -pthread" "${FULCRUM_DETERMINISM_CFLAGS}")
fulcrum_pkg_config(fulcrum-scenes "Fulcrum: scene builders and the built-in scenes"
                   "fulcrum-engine" "-lfulcrum_scenes" "")
fulcrum_pkg_config(fulcrum-proto "Fulcrum: protobuf messages of fulcrum.v1" "protobuf"
                   "-lfulcrum_proto" "")
# The scene files' builders come from the scene builders.
fulcrum_pkg_config(fulcrum-convert
                   "Fulcrum: scene loader, snapshots, edits and replays (proto <-> engine)"
                   "fulcrum-scenes fulcrum-proto" "-lfulcrum_convert" "")
fulcrum_pkg_config(fulcrum-client "Fulcrum: client of the Physics service"
                   "fulcrum-convert grpc++" "-lfulcrum_client -lfulcrum_grpc" "")
