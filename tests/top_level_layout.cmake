# Fails when git tracks a top-level entry outside the design card's layout (modules/ apps/
# tests/ data/ tools/ CMakeLists.txt CMakePresets.json, plus docs, CMake helpers, CI and the
# README): scratch logs and decks once landed at the top level unnoticed. Outside a git
# checkout (a source tarball) there is nothing to check.
# usage: cmake -DSOURCE_DIR=<root> -P top_level_layout.cmake
set(allowed .ci .gitignore CMakeLists.txt CMakePresets.json README.md apps cmake data docs modules tests tools)
find_program(GIT git)
if(NOT GIT OR NOT EXISTS "${SOURCE_DIR}/.git")
  message(STATUS "not a git checkout: layout not checked")
  return()
endif()
execute_process(COMMAND "${GIT}" -C "${SOURCE_DIR}" ls-files RESULT_VARIABLE rc OUTPUT_VARIABLE files ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  # git refusing the checkout (another owner's tree, safe.directory) says nothing of its layout.
  message(STATUS "git ls-files failed, layout not checked: ${err}")
  return()
endif()
string(REGEX REPLACE "\n$" "" files "${files}")
string(REPLACE "\n" ";" files "${files}")
set(stray "")
foreach(f IN LISTS files)
  string(REGEX REPLACE "/.*" "" top "${f}")
  if(NOT top IN_LIST allowed AND NOT top IN_LIST stray)
    list(APPEND stray "${top}")
  endif()
endforeach()
list(LENGTH stray n)
if(n GREATER 0)
  if(n GREATER 10)
    list(SUBLIST stray 0 10 stray)
  endif()
  message(FATAL_ERROR "${n} tracked top-level entries outside the layout (first ones: ${stray}); move them under tools/, docs/ or data/, or remove them")
endif()
