# Install and package (issue 13): `cmake --install` puts the C API headers, the shared
# libedgephys, the relay and PhyS worker binaries, a CMake package (find_package(edgephys),
# target edgephys::edgephys) and a pkg-config file (edgephys.pc) under the prefix; `cpack -G DEB`
# builds a Debian package of the same tree. tests/install_consumer_test.sh checks both ways
# of consuming it.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/edgephys
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT sdk
        FILES_MATCHING PATTERN "*.h" PATTERN "*.hpp")
install(TARGETS edgephys_shared EXPORT edgephysTargets
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT sdk NAMELINK_COMPONENT sdk
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
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

# The language bindings. Each finds the installed libedgephys with no environment variable:
#  * Python: share/edgephys/bindings/python is a pip-installable package whose
#    edgephys/_install.py (written here, at install time, so `--prefix` and DESTDIR hold) names
#    the library: `pip install <prefix>/share/edgephys/bindings/python`.
#  * C#: lib/edgephys/dotnet/Edgephys.dll (built with mcs when Mono is present) and its
#    Edgephys.dll.config, whose dllmap points Mono at the installed library: reference the
#    assembly and copy both files next to the application.
install(DIRECTORY ${PROJECT_SOURCE_DIR}/bindings/ DESTINATION ${CMAKE_INSTALL_DATADIR}/edgephys/bindings
        COMPONENT sdk PATTERN "__pycache__" EXCLUDE PATTERN "*.exe" EXCLUDE PATTERN "*.dll" EXCLUDE
        PATTERN "_install.py" EXCLUDE PATTERN "build" EXCLUDE PATTERN "*.egg-info" EXCLUDE)
set(EDGEPHYS_INSTALLED_LIB "${CMAKE_INSTALL_LIBDIR}/libedgephys.so.1")
install(CODE "
  set(lib \"\${CMAKE_INSTALL_PREFIX}/${EDGEPHYS_INSTALLED_LIB}\")
  file(WRITE \"\$ENV{DESTDIR}\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_DATADIR}/edgephys/bindings/python/edgephys/_install.py\"
       \"# Written by cmake --install: the libedgephys this package was installed with.\\nLIBRARY = '\${lib}'\\n\")
  if(EXISTS \"${PROJECT_BINARY_DIR}/examples/csharp/Edgephys.dll\")
    set(dotnet \"\$ENV{DESTDIR}\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_LIBDIR}/edgephys/dotnet\")
    file(INSTALL \"${PROJECT_BINARY_DIR}/examples/csharp/Edgephys.dll\" DESTINATION \"\${dotnet}\")
    file(WRITE \"\${dotnet}/Edgephys.dll.config\"
         \"<configuration>\\n  <dllmap dll=\\\"edgephys\\\" target=\\\"\${lib}\\\"/>\\n</configuration>\\n\")
  endif()
" COMPONENT sdk)

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
