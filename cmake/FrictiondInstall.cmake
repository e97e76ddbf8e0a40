# Install proto, estimators, crypto and client with an exported CMake package
# so that an outside project can do:
#   find_package(frictiond CONFIG REQUIRED)
#   target_link_libraries(robot_app PRIVATE frictiond::client)
# and, when built with LCM, the LCM types and the bounds-checked codec with
# the signed-message receiver (find_package(frictiond COMPONENTS lcm)):
#   target_link_libraries(robot_app PRIVATE frictiond::lcm_codec)
include(CMakePackageConfigHelpers)

install(TARGETS frictiond_estimators frictiond_proto frictiond_crypto frictiond_client
  EXPORT frictiondTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
foreach(_dir estimators proto crypto client)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${_dir}/include/frictiond
    DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endforeach()
# Component lcm: the generated message types (frictiond::lcmtypes, headers
# below) and frictiond::lcm_codec (lcm_codec.h, lcm_signed.h).
set(FRICTIOND_HAVE_LCM_CODEC OFF)
if(TARGET frictiond_lcm_codec)
  set(FRICTIOND_HAVE_LCM_CODEC ON)
  install(TARGETS frictiond_lcmtypes frictiond_lcm_codec EXPORT frictiondTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/proto/lcm/include/frictiond
    DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endif()
# The MuJoCo adapter: find_package(frictiond COMPONENTS mujoco).
if(TARGET frictiond_mujoco)
  install(TARGETS frictiond_mujoco EXPORT frictiondTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/sim/mujoco/include/frictiond
    DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endif()
if(TARGET frictiond_lcmtypes)
  install(DIRECTORY ${CMAKE_BINARY_DIR}/lcmtypes/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endif()
install(TARGETS frictiond friction RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

set(_cfgdir ${CMAKE_INSTALL_LIBDIR}/cmake/frictiond)
install(EXPORT frictiondTargets NAMESPACE frictiond:: DESTINATION ${_cfgdir})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/frictiondConfig.cmake.in
  ${CMAKE_BINARY_DIR}/frictiondConfig.cmake INSTALL_DESTINATION ${_cfgdir})
write_basic_package_version_file(${CMAKE_BINARY_DIR}/frictiondConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMajorVersion)
install(FILES ${CMAKE_BINARY_DIR}/frictiondConfig.cmake
  ${CMAKE_BINARY_DIR}/frictiondConfigVersion.cmake DESTINATION ${_cfgdir})

# The bundled measured datasets (with their LICENSE and PROVENANCE) and the
# deployment files, so an installed daemon needs no source tree.
install(DIRECTORY ${PROJECT_SOURCE_DIR}/data/ DESTINATION ${CMAKE_INSTALL_DATADIR}/frictiond/data)
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(FILES ${PROJECT_SOURCE_DIR}/deploy/systemd/frictiond.service
  ${PROJECT_SOURCE_DIR}/deploy/frictiond.example.json
  DESTINATION ${CMAKE_INSTALL_DATADIR}/frictiond/deploy)
