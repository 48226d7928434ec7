# peridot_add_module(<name> SOURCES <cppm...> [IMPORTS <peridot modules>] [LIBS <libs>])
# One named C++20 module per concern; target peridot_<name>, alias peridot::<name>.
function(peridot_add_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;IMPORTS;LIBS" ${ARGN})
  set(target peridot_${name})
  # A standard header in a unit's global fragment costs clang 19 15-40 s of merging it with the
  # copy its imports hold (see modules/std/CMakeLists.txt): units import peridot.std instead.
  if(NOT name STREQUAL "std")
    foreach(source IN LISTS ARG_SOURCES)
      file(STRINGS ${CMAKE_CURRENT_SOURCE_DIR}/${source} std_includes REGEX "^#include <([a-z_]+|fmt/[a-z]+\\.h)>")
      if(std_includes)
        message(FATAL_ERROR "modules/${name}/${source}: ${std_includes}: import peridot.std instead (add the name to "
                            "modules/std/std.cppm if it is missing); C headers (<stdio.h>) are fine")
      endif()
    endforeach()
  endif()
  add_library(${target} STATIC)
  add_library(peridot::${name} ALIAS ${target})
  target_sources(${target} PUBLIC FILE_SET CXX_MODULES FILES ${ARG_SOURCES})
  target_compile_features(${target} PUBLIC cxx_std_20)
  # peridot.std, imported by every unit in place of standard headers (modules/std).
  if(NOT name STREQUAL "std")
    target_link_libraries(${target} PUBLIC peridot::std)
  endif()
  foreach(dep IN LISTS ARG_IMPORTS)
    target_link_libraries(${target} PUBLIC peridot::${dep})
  endforeach()
  # Every module and consumer must share the OpenMP setting, or the BMIs will not load.
  target_link_libraries(${target} PUBLIC OpenMP::OpenMP_CXX ${ARG_LIBS})
endfunction()
