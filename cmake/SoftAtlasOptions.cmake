# Warnings, tuning and sanitizers shared by every SoftAtlas target.
add_library(softatlas_options INTERFACE)
target_compile_options(softatlas_options INTERFACE
  $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wpedantic -Wno-unused-parameter>)
if(SOFTATLAS_WERROR)
  # A clean build prints no warning (issue 17); CI builds with -DSOFTATLAS_WERROR=ON.
  target_compile_options(softatlas_options INTERFACE $<$<CXX_COMPILER_ID:GNU,Clang>:-Werror>)
endif()
if(SOFTATLAS_NATIVE)
  include(CheckCXXCompilerFlag)
  check_cxx_compiler_flag(-march=native SOFTATLAS_HAS_MARCH_NATIVE)
  if(SOFTATLAS_HAS_MARCH_NATIVE)
    target_compile_options(softatlas_options INTERFACE -march=native)
  endif()
endif()
if(SOFTATLAS_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "SOFTATLAS_FUZZ=ON needs clang (CC=clang-14 CXX=clang++-14), found ${CMAKE_CXX_COMPILER_ID}")
  endif()
  if(NOT SOFTATLAS_SANITIZE)
    set(SOFTATLAS_SANITIZE address,undefined)
  endif()
  # Coverage instrumentation everywhere; only the fuzz_* executables link libFuzzer's main.
  target_compile_options(softatlas_options INTERFACE -fsanitize=fuzzer-no-link)
  target_link_options(softatlas_options INTERFACE -fsanitize=fuzzer-no-link)
endif()
if(SOFTATLAS_SANITIZE)
  target_compile_options(softatlas_options INTERFACE
    -fsanitize=${SOFTATLAS_SANITIZE} -fno-omit-frame-pointer -fno-sanitize-recover=all)
  target_link_options(softatlas_options INTERFACE -fsanitize=${SOFTATLAS_SANITIZE})
  # Line tables for the reports' file:line. GCC's -Wmaybe-uninitialized is unreliable under the
  # sanitizers' instrumentation (false reports inside libstdc++'s <regex> and <functional> in a
  # Release build with -fsanitize=address,undefined): off there, every other warning stays an error.
  # Clang: the instrumentation keeps `#pragma omp simd` loops from vectorizing, which clang reports
  # (-Wpass-failed); the plain build vectorizes them and keeps the warning.
  target_compile_options(softatlas_options INTERFACE $<$<CXX_COMPILER_ID:GNU>:-g1 -Wno-maybe-uninitialized>
                                                     $<$<CXX_COMPILER_ID:Clang>:-gline-tables-only -Wno-pass-failed>)
endif()

# softatlas_add_test(NAME sources... LIBS libs... [LABELS l...]): one GoogleTest executable,
# registered test by test (gtest_discover_tests), with the shared data folder as a definition.
include(GoogleTest)
function(softatlas_add_test name)
  cmake_parse_arguments(T "" "TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE ${T_LIBS} GTest::gtest GTest::gtest_main softatlas_options)
  target_compile_definitions(${name} PRIVATE
    SOFTATLAS_SHARED_DATA="${SOFTATLAS_SHARED_DATA}"
    SOFTATLAS_SOURCE_DIR="${SOFTATLAS_SOURCE_DIR}"
    SOFTATLAS_BINARY_DIR="${CMAKE_BINARY_DIR}")
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 600)
  endif()
  set(props TIMEOUT ${T_TIMEOUT})
  if(T_LABELS)
    list(APPEND props LABELS "${T_LABELS}")
  endif()
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60
    PROPERTIES ${props}
    WORKING_DIRECTORY ${CMAKE_BINARY_DIR})
endfunction()
