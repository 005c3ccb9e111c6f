# The include graph of geotraj's own code, checked at configure time (a violation fails the
# configure step, so the build): each folder includes only what is below it, never above.
#
#   core/error.hpp, core/format.hpp    error values and the number formatter every layer shares
#   core/geometry   core/robot         key frames to curves; arms (independent of each other)
#   core/motion                        u = f(t) and the tool's orientation, on geometry
#   core/planning                      trajectories of every kind: motion + robot
#   core/live                          live execution and jogging, on planning
#   optim/common                       report, solver lock, AD type
#   optim/<problem>                    one optimisation problem each, on core and optim/common
#   planner                            the application layer, on core and optim
#   server/wire < server/ops < server/web < server/rpc < server/main.cpp
#                                      proto <-> planner values; runtime, metrics, logs, HTTP;
#                                      the JSON/HTTP gateway; reactors; the process.
#                                      server/server.hpp and server/status_codes.hpp are the
#                                      server's public face; below rpc only its configuration
#                                      values (server/options.hpp), not the running server.
#   client                             the CLI: the server's public face (it runs the service
#                                      in process without --server), the wire's conversions
#                                      (both ends read the same proto), the planner's robots
#                                      and core's values; never ops, web or rpc.
# Generated and third-party headers (<...>, geotraj/v1/..., grpc/...) are not this graph's;
# core, optim and planner must not include gRPC or protobuf at all (below).

set(_core_shared "core/(error|format)\\.hpp")
set(_core_all "(${_core_shared}|core/(geometry|robot|motion|planning|live)/)")
set(_optim_all "optim/(common|tangent_scales|breakpoints|timing|redundancy)/")
# folder (relative to the project root) -> the project include prefixes it may use
set(_layer_folders
  core/geometry core/robot core/motion core/planning core/live
  optim/common optim/tangent_scales optim/breakpoints optim/timing optim/redundancy
  planner server/wire server/ops server/web server/rpc client)
set(_allowed_core/geometry "^(${_core_shared}|core/geometry/)")
set(_allowed_core/robot "^(${_core_shared}|core/robot/)")
set(_allowed_core/motion "^(${_core_shared}|core/(geometry|motion)/)")
set(_allowed_core/planning "^(${_core_shared}|core/(geometry|robot|motion|planning)/)")
set(_allowed_core/live "^${_core_all}")
set(_allowed_optim/common "^(${_core_shared}|optim/common/)")
set(_allowed_optim/tangent_scales "^(${_core_all}|optim/(common|tangent_scales)/)")
set(_allowed_optim/breakpoints "^(${_core_all}|optim/(common|breakpoints)/)")
set(_allowed_optim/timing "^(${_core_all}|optim/(common|timing)/)")
set(_allowed_optim/redundancy "^(${_core_all}|optim/(common|redundancy)/)")
set(_allowed_planner "^(${_core_all}|${_optim_all}|planner/)")
set(_allowed_server/wire "^(${_core_all}|${_optim_all}|planner/|server/(wire/|status_codes\\.hpp|options\\.hpp))")
set(_allowed_server/ops "^(server/(wire/|ops/|status_codes\\.hpp|options\\.hpp))")
set(_allowed_server/web "^(${_core_shared}|server/(wire/|ops/|web/|status_codes\\.hpp|options\\.hpp))")
set(_allowed_server/rpc "^(${_core_all}|${_optim_all}|planner/|server/(wire|ops|web|rpc)/|server/(status_codes|options|server)\\.hpp)")
set(_allowed_client "^(${_core_all}|planner/|client/|server/(wire/|status_codes\\.hpp|options\\.hpp|server\\.hpp))")

foreach(_folder IN LISTS _layer_folders)
  file(GLOB_RECURSE _files CONFIGURE_DEPENDS
    ${PROJECT_SOURCE_DIR}/${_folder}/*.hpp ${PROJECT_SOURCE_DIR}/${_folder}/*.cpp)
  foreach(_file IN LISTS _files)
    file(STRINGS "${_file}" _includes REGEX "^[ \t]*#[ \t]*include[ \t]*\"(core|optim|planner|server)/")
    foreach(_line IN LISTS _includes)
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*\"([^\"]+)\".*" "\\1" _included "${_line}")
      if(NOT _included MATCHES "${_allowed_${_folder}}")
        file(RELATIVE_PATH _rel ${PROJECT_SOURCE_DIR} ${_file})
        message(FATAL_ERROR "layering: ${_rel} includes \"${_included}\", which is not below ${_folder}/ "
                            "(cmake/layering.cmake has the graph)")
      endif()
    endforeach()
  endforeach()
endforeach()

# The process (server/main.cpp) may include all of the server, and nothing includes it.
file(STRINGS ${PROJECT_SOURCE_DIR}/server/main.cpp _includes REGEX "^[ \t]*#[ \t]*include[ \t]*\"(core|optim|planner|server)/")
foreach(_line IN LISTS _includes)
  string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*\"([^\"]+)\".*" "\\1" _included "${_line}")
  if(NOT _included MATCHES "^(${_core_all}|${_optim_all}|planner/|server/)")
    message(FATAL_ERROR "layering: server/main.cpp includes \"${_included}\" (cmake/layering.cmake has the graph)")
  endif()
endforeach()

# Nothing under core/, optim/ or planner/ includes gRPC or protobuf headers.
foreach(_layer core optim planner)
  file(GLOB_RECURSE _layer_files CONFIGURE_DEPENDS
    ${PROJECT_SOURCE_DIR}/${_layer}/*.hpp ${PROJECT_SOURCE_DIR}/${_layer}/*.cpp)
  foreach(_file IN LISTS _layer_files)
    file(STRINGS "${_file}" _wire REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"](grpc|grpcpp|google/protobuf|google/rpc|geotraj/v1|server)[/.]")
    if(_wire)
      message(FATAL_ERROR "layering: ${_file} includes a wire header (${_wire}); ${_layer}/ must not know gRPC or protobuf")
    endif()
  endforeach()
endforeach()
