# FRICTIOND_SANITIZE: "address;undefined" or "thread". Refuses combinations
# that cannot work together (TSan with ASan) and checks compiler support.
if(FRICTIOND_SANITIZE)
  include(CheckCXXSourceCompiles)
  set(_san ${FRICTIOND_SANITIZE})
  if("thread" IN_LIST _san AND ("address" IN_LIST _san OR "memory" IN_LIST _san))
    message(FATAL_ERROR "FRICTIOND_SANITIZE='${FRICTIOND_SANITIZE}': 'thread' cannot be combined with 'address' or 'memory'")
  endif()
  foreach(_s ${_san})
    if(NOT _s MATCHES "^(address|undefined|thread|leak)$")
      message(FATAL_ERROR "FRICTIOND_SANITIZE: unknown sanitizer '${_s}' (allowed: address, undefined, thread, leak)")
    endif()
  endforeach()
  string(REPLACE ";" "," _flag "${_san}")
  set(CMAKE_REQUIRED_FLAGS "-fsanitize=${_flag}")
  set(CMAKE_REQUIRED_LINK_OPTIONS "-fsanitize=${_flag}")
  check_cxx_source_compiles("int main() { return 0; }" FRICTIOND_SANITIZER_WORKS)
  unset(CMAKE_REQUIRED_FLAGS)
  unset(CMAKE_REQUIRED_LINK_OPTIONS)
  if(NOT FRICTIOND_SANITIZER_WORKS)
    message(FATAL_ERROR "the compiler does not support -fsanitize=${_flag}")
  endif()
  add_compile_options(-fsanitize=${_flag} -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  add_link_options(-fsanitize=${_flag})
endif()

# FRICTIOND_BUILD_FUZZERS: libFuzzer harnesses (frictiond_add_fuzzer,
# deploy/fuzz.sh). Needs clang (CC=clang CXX=clang++); every target is built
# with coverage instrumentation plus ASan and UBSan, so configure it in its
# own build directory (build-fuzz).
if(FRICTIOND_BUILD_FUZZERS)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "FRICTIOND_BUILD_FUZZERS needs clang (configure with CC=clang CXX=clang++), not ${CMAKE_CXX_COMPILER_ID}")
  endif()
  if(FRICTIOND_SANITIZE)
    message(FATAL_ERROR "FRICTIOND_BUILD_FUZZERS brings its own sanitizers (address, undefined); leave FRICTIOND_SANITIZE empty")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer
    -fno-sanitize-recover=undefined)
  add_link_options(-fsanitize=address,undefined)
  add_custom_target(frictiond_fuzzers)
  file(WRITE ${CMAKE_BINARY_DIR}/fuzzers.txt "")
endif()
