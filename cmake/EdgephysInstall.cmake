# Install and package: `cmake --install` puts the C API headers, the shared libedgephys, the
# relay and PhyS worker binaries, a CMake package (find_package(edgephys), target
# edgephys::edgephys), a pkg-config file (edgephys.pc), the Python package and the C# assembly
# under the prefix; `cpack -G DEB` builds a Debian package of the same tree. Everything loads
# from the prefix with no environment variables: the binaries carry an rpath to the prefix's
# libdir, edgephys.pc adds one to its consumers, the Python package and Edgephys.dll.config name
# the installed library. tests/install_consumer_test.sh and tests/install_sdk_test.sh check it.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/edgephys
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT sdk
        FILES_MATCHING PATTERN "*.h" PATTERN "*.hpp")
install(TARGETS edgephys_shared EXPORT edgephysTargets
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT sdk NAMELINK_COMPONENT sdk
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
set_target_properties(edgephys-relay edgephys-phys PROPERTIES
                      INSTALL_RPATH "$ORIGIN/../${CMAKE_INSTALL_LIBDIR}")
install(TARGETS edgephys-relay edgephys-phys RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT server)

set(EDGEPHYS_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/edgephys)
install(EXPORT edgephysTargets NAMESPACE edgephys:: DESTINATION ${EDGEPHYS_CMAKE_DIR} COMPONENT sdk)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/edgephysConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/edgephysConfig.cmake
                              INSTALL_DESTINATION ${EDGEPHYS_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/edgephysConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/edgephysConfig.cmake ${PROJECT_BINARY_DIR}/edgephysConfigVersion.cmake
        DESTINATION ${EDGEPHYS_CMAKE_DIR} COMPONENT sdk)

# Relocatable: the prefix is found from the .pc file's own place (cmake --install --prefix X).
file(RELATIVE_PATH EDGEPHYS_PC_TO_PREFIX "/p/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/p")
configure_file(${PROJECT_SOURCE_DIR}/cmake/edgephys.pc.in ${PROJECT_BINARY_DIR}/edgephys.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/edgephys.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT sdk)

# The language bindings (sources, the Python package with its pyproject.toml, the C# binding)
# and the SDK examples.
set(EDGEPHYS_BINDINGS_DIR ${CMAKE_INSTALL_DATADIR}/edgephys/bindings)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/bindings/ DESTINATION ${EDGEPHYS_BINDINGS_DIR}
        COMPONENT sdk PATTERN "__pycache__" EXCLUDE PATTERN "*.exe" EXCLUDE PATTERN "*.dll" EXCLUDE
        PATTERN "*.egg-info" EXCLUDE PATTERN "python/build" EXCLUDE PATTERN "_libdir.py" EXCLUDE PATTERN ".gitignore" EXCLUDE)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/examples/ DESTINATION ${CMAKE_INSTALL_DATADIR}/edgephys/examples
        COMPONENT sdk PATTERN "CMakeLists.txt" EXCLUDE)

# The C# package: Edgephys.cs, the assembly built with mcs (examples/CMakeLists.txt) and, at
# install time, its Edgephys.dll.config.
if(TARGET edgephys_csharp)
  install(FILES ${PROJECT_BINARY_DIR}/examples/csharp/Edgephys.dll
          DESTINATION ${EDGEPHYS_BINDINGS_DIR}/csharp COMPONENT sdk)
endif()
# Where the installed library is, written into the installed bindings by cmake --install (so
# --prefix X and DESTDIR staging both name the final place): cmake/edgephys_install_paths.cmake.in.
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)  # the .deb's prefix (CPack, below)
configure_file(${PROJECT_SOURCE_DIR}/cmake/edgephys_install_paths.cmake.in
               ${PROJECT_BINARY_DIR}/edgephys_install_paths.cmake @ONLY)
install(SCRIPT ${PROJECT_BINARY_DIR}/edgephys_install_paths.cmake COMPONENT sdk)

# CPack: one .deb with everything (cpack -G DEB in the build directory).
set(CPACK_PACKAGE_NAME edgephys)
set(CPACK_PACKAGE_VENDOR "edgephys")
set(CPACK_PACKAGE_CONTACT "edgephys maintainers <edgephys@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "edgephys: UDP relay with physics offload, and its client SDK (C API)")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_GENERATOR DEB)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION net)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)  # Depends: from dpkg-shlibdeps (spdlog, bullet, ...)
set(CPACK_STRIP_FILES ON)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
include(CPack)
