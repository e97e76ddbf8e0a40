# LCM message types (CONTRACT.md "LCM"): proto/*.lcm, package frictiond,
# generated to C++ headers with lcm-gen at build time into the build tree
# (never into the source tree). Included by proto/CMakeLists.txt when
# FRICTIOND_WITH_LCM is ON.
file(GLOB _lcm_types CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.lcm)
set(_lcm_out ${CMAKE_BINARY_DIR}/lcmtypes/include)  # installed by FrictiondInstall
set(_lcm_headers)
foreach(_f ${_lcm_types})
  get_filename_component(_n ${_f} NAME_WE)
  list(APPEND _lcm_headers ${_lcm_out}/frictiond/${_n}.hpp)
endforeach()
add_custom_command(
  OUTPUT ${_lcm_headers}
  COMMAND ${CMAKE_COMMAND} -E make_directory ${_lcm_out}
  COMMAND ${LCM_GEN} --cpp --cpp-hpath ${_lcm_out} ${_lcm_types}
  DEPENDS ${_lcm_types}
  COMMENT "lcm-gen --cpp: frictiond LCM message types"
  VERBATIM)
add_custom_target(frictiond_lcmtypes_gen DEPENDS ${_lcm_headers})

# Header-only target of the generated types: #include "frictiond/<type>.hpp".
add_library(frictiond_lcmtypes INTERFACE)
add_library(frictiond::lcmtypes ALIAS frictiond_lcmtypes)
set_target_properties(frictiond_lcmtypes PROPERTIES EXPORT_NAME lcmtypes)
add_dependencies(frictiond_lcmtypes frictiond_lcmtypes_gen)
# SYSTEM: generated code is not held to our warning flags.
target_include_directories(frictiond_lcmtypes SYSTEM INTERFACE
  $<BUILD_INTERFACE:${_lcm_out}>
  $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
target_link_libraries(frictiond_lcmtypes INTERFACE PkgConfig::LCM)
target_compile_definitions(frictiond_lcmtypes INTERFACE FRICTIOND_HAVE_LCM=1)

# Bounds-checked decoders of the message types (proto/lcm/, lcm_codec.h):
# the codec half of the LCM endpoint, used by the daemon, the robot
# simulator and the fuzz harnesses; no socket or liblcm call. Installed and
# exported as frictiond::lcm_codec (FrictiondInstall.cmake), so that a robot
# verifies the daemon's signed messages with LcmSignedReceiver.
add_library(frictiond_lcm_codec STATIC ${CMAKE_CURRENT_SOURCE_DIR}/lcm/src/lcm_codec.cc
  ${CMAKE_CURRENT_SOURCE_DIR}/lcm/src/lcm_signed.cc)
add_library(frictiond::lcm_codec ALIAS frictiond_lcm_codec)
set_target_properties(frictiond_lcm_codec PROPERTIES EXPORT_NAME lcm_codec)
target_include_directories(frictiond_lcm_codec PUBLIC
  $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/lcm/include>
  $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
target_link_libraries(frictiond_lcm_codec PUBLIC frictiond_lcmtypes frictiond::proto frictiond::crypto)
target_compile_features(frictiond_lcm_codec PUBLIC cxx_std_17)
frictiond_warnings(frictiond_lcm_codec)
if(FRICTIOND_BUILD_TESTS)
  foreach(_n lcm_codec_test lcm_signed_test)
    frictiond_add_test(${_n} SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/lcm/test/${_n}.cc
      LIBS frictiond::lcm_codec)
  endforeach()
endif()
frictiond_add_fuzzer(lcm_codec_fuzzer SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/lcm/test/lcm_codec_fuzzer.cc
  LIBS frictiond::lcm_codec)
