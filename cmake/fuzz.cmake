# Builds the libFuzzer targets (fuzz/) with clang into build/fuzz and registers
# a short smoke run of each as a ctest entry: every target replays its seed
# corpus and then mutates for RAYFARM_FUZZ_SMOKE_RUNS inputs with a fixed seed.
# `make fuzz` runs them for minutes each (fuzz/run.sh). ON when clang is found.
find_program(RAYFARM_CLANGXX NAMES clang++ clang++-14)
if(RAYFARM_CLANGXX)
  set(fuzz_default ON)
else()
  set(fuzz_default OFF)
endif()
option(RAYFARM_FUZZ "build the fuzz targets (needs clang and libclang-rt) and smoke-test them" ${fuzz_default})
set(RAYFARM_FUZZ_SMOKE_RUNS 3000 CACHE STRING "inputs each fuzz target mutates in its ctest smoke run")

if(RAYFARM_FUZZ)
  if(NOT RAYFARM_CLANGXX)
    message(FATAL_ERROR "RAYFARM_FUZZ needs clang++ (apt-get install clang libclang-rt-14-dev)")
  endif()
  include(ExternalProject)
  ExternalProject_Add(rayfarm_fuzz
    SOURCE_DIR ${PROJECT_SOURCE_DIR}/fuzz
    BINARY_DIR ${CMAKE_BINARY_DIR}/fuzz
    CMAKE_ARGS -DCMAKE_CXX_COMPILER=${RAYFARM_CLANGXX}
               -DCMAKE_CXX_COMPILER_LAUNCHER=${CMAKE_CXX_COMPILER_LAUNCHER}
    INSTALL_COMMAND ""
    BUILD_ALWAYS ON)

  file(GLOB fuzz_sources CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/fuzz/*_fuzz.cpp)
  foreach(source IN LISTS fuzz_sources)
    get_filename_component(stem ${source} NAME_WE)
    string(REGEX REPLACE "_fuzz$" "" name ${stem})
    add_test(NAME "fuzz: ${name} smoke"
             COMMAND ${PROJECT_SOURCE_DIR}/fuzz/run.sh ${CMAKE_BINARY_DIR}/fuzz ${name}
                     -runs=${RAYFARM_FUZZ_SMOKE_RUNS} -seed=1 -timeout=20 -rss_limit_mb=2048)
  endforeach()
endif()
