# Extra wiring of the cross-module tests (included by tests/CMakeLists.txt).

# The daemon launcher in frictiond_testing (daemon_process.h) uses
# cpp-httplib; its ABI depends on the pkg-config macros, so take them from
# the same interface target as the server.
target_link_libraries(frictiond_testing PUBLIC frictiond_httplib)

# The crash-safety test opens the database with SQLite directly to run
# PRAGMA integrity_check after SIGKILLs.
if(TARGET crash_safety_test)
  target_link_libraries(crash_safety_test PRIVATE SQLite::SQLite3)
  set_tests_properties(crash_safety_test PROPERTIES TIMEOUT 120)
endif()
# The hostile-input test builds a gzip bomb with zlib (a dependency of
# cpp-httplib already).
if(TARGET http_hostile_test)
  find_package(ZLIB REQUIRED)
  target_link_libraries(http_hostile_test PRIVATE ZLIB::ZLIB)
  set_tests_properties(http_hostile_test PROPERTIES TIMEOUT 120)
endif()
# The daemon's allocator (jemalloc when the build links it), named in its
# heap gauges' help text.
if(TARGET http_api_test AND FRICTIOND_HAVE_JEMALLOC)
  target_compile_definitions(http_api_test PRIVATE FRICTIOND_DAEMON_JEMALLOC=1)
endif()
foreach(_t http_api_test bad_input_test crash_safety_test http_hostile_test)
  if(TARGET ${_t})
    set_tests_properties(${_t} PROPERTIES LABELS "daemon")
  endif()
endforeach()

# LCM tests and the simulated robot (need the generated LCM types).
if(TARGET frictiond_lcmtypes)
  add_subdirectory(lcm)
endif()

# Deployment files: install tree, example config, systemd unit.
add_test(NAME deploy_files COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/deploy/check_deploy.sh ${CMAKE_BINARY_DIR})
set_tests_properties(deploy_files PROPERTIES TIMEOUT 120 LABELS "install" SKIP_RETURN_CODE 77)

# The operator console in a real browser: headless Debian chromium driven by
# puppeteer-core (tests/browser, docs/console.md). Screenshots go to
# build/test-artifacts/console-*.png.
add_test(NAME console_browser_test
  COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/browser/run.sh ${CMAKE_BINARY_DIR})
set_tests_properties(console_browser_test PROPERTIES LABELS "browser" TIMEOUT 120)
