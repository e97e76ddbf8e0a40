# frictiond_library(NAME <name> [PUBLIC_LIBS ...] [PRIVATE_LIBS ...]
#                   [TEST_LIBS ...] [FUZZ_LIBS ...])
# One folder, one library: sources are src/*.cc, public headers are
# include/frictiond/<name>/*.h, unit tests are test/*_test.cc.
function(frictiond_library)
  cmake_parse_arguments(ARG "" "NAME" "PUBLIC_LIBS;PRIVATE_LIBS;TEST_LIBS;FUZZ_LIBS" ${ARGN})
  file(GLOB _srcs CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/src/*.cc)
  add_library(frictiond_${ARG_NAME} ${_srcs})
  add_library(frictiond::${ARG_NAME} ALIAS frictiond_${ARG_NAME})
  set_target_properties(frictiond_${ARG_NAME} PROPERTIES EXPORT_NAME ${ARG_NAME})
  target_compile_features(frictiond_${ARG_NAME} PUBLIC cxx_std_17)
  target_include_directories(frictiond_${ARG_NAME} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(frictiond_${ARG_NAME} PUBLIC ${ARG_PUBLIC_LIBS} PRIVATE ${ARG_PRIVATE_LIBS})
  frictiond_warnings(frictiond_${ARG_NAME})
  if(FRICTIOND_BUILD_TESTS)
    file(GLOB _tests CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/test/*_test.cc)
    foreach(_t ${_tests})
      get_filename_component(_n ${_t} NAME_WE)
      frictiond_add_test(${_n} SOURCES ${_t} LIBS frictiond::${ARG_NAME} ${ARG_TEST_LIBS})
    endforeach()
  endif()
  # libFuzzer harnesses beside the unit tests (STYLE.md 16): test/*_fuzzer.cc,
  # linked with this library and FUZZ_LIBS; seeds in test/corpus/<name>/.
  file(GLOB _fuzzers CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/test/*_fuzzer.cc)
  foreach(_f ${_fuzzers})
    get_filename_component(_n ${_f} NAME_WE)
    frictiond_add_fuzzer(${_n} SOURCES ${_f} LIBS frictiond::${ARG_NAME} ${ARG_FUZZ_LIBS})
  endforeach()
endfunction()

function(frictiond_warnings target)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic)
  endif()
endfunction()

# frictiond_add_test(<name> SOURCES ... LIBS ... [LABELS ...])
function(frictiond_add_test name)
  cmake_parse_arguments(ARG "" "" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} frictiond_testing GTest::gtest GTest::gtest_main)
  frictiond_warnings(${name})
  add_test(NAME ${name} COMMAND ${name})
  set_tests_properties(${name} PROPERTIES
    ENVIRONMENT "FRICTIOND_SOURCE_DIR=${PROJECT_SOURCE_DIR};FRICTIOND_BIN_DIR=${CMAKE_BINARY_DIR}/bin"
    TIMEOUT 600)
  if(ARG_LABELS)
    set_tests_properties(${name} PROPERTIES LABELS "${ARG_LABELS}")
  endif()
endfunction()

# frictiond_add_fuzzer(<name> SOURCES ... LIBS ... [CORPUS <dir>])
# One libFuzzer harness (docs/fuzzing.md). A no-op unless
# FRICTIOND_BUILD_FUZZERS is ON (then the whole build is instrumented with
# -fsanitize=fuzzer-no-link,address,undefined, see FrictiondSanitizers.cmake).
# The harness defines LLVMFuzzerTestOneInput and is linked with
# -fsanitize=fuzzer. Its committed seed corpus is CORPUS (default:
# <dir of the first source>/corpus/<name>). Each harness is written to
# <build>/fuzzers.txt as "name<TAB>binary<TAB>corpus", which deploy/fuzz.sh
# reads; the target frictiond_fuzzers builds them all (and only what they
# need). Harnesses in a library folder's test/*_fuzzer.cc are registered by
# frictiond_library; others call this directly.
function(frictiond_add_fuzzer name)
  if(NOT FRICTIOND_BUILD_FUZZERS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "CORPUS" "SOURCES;LIBS" ${ARGN})
  list(GET ARG_SOURCES 0 _first)
  get_filename_component(_dir ${_first} DIRECTORY)
  if(NOT IS_ABSOLUTE "${_dir}")
    set(_dir ${CMAKE_CURRENT_SOURCE_DIR}/${_dir})
  endif()
  if(NOT ARG_CORPUS)
    set(ARG_CORPUS ${_dir}/corpus/${name})
  endif()
  if(NOT IS_DIRECTORY ${ARG_CORPUS})
    message(FATAL_ERROR "fuzzer ${name}: no seed corpus at ${ARG_CORPUS}")
  endif()
  add_executable(${name} ${ARG_SOURCES})
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/fuzz)
  target_link_libraries(${name} PRIVATE ${ARG_LIBS})
  target_link_options(${name} PRIVATE -fsanitize=fuzzer)
  frictiond_warnings(${name})
  add_dependencies(frictiond_fuzzers ${name})
  file(APPEND ${CMAKE_BINARY_DIR}/fuzzers.txt "${name}\t${CMAKE_BINARY_DIR}/fuzz/${name}\t${ARG_CORPUS}\n")
endfunction()
