# Project-wide warning and sanitizer flags, applied through edgephys_set_options(target).
function(edgephys_set_options target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
                                           -Wold-style-cast -Wcast-align -Woverloaded-virtual
                                           -Wimplicit-fallthrough
                                           -Wno-missing-field-initializers)
  if(EDGEPHYS_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

if(EDGEPHYS_SANITIZE)
  if(NOT EDGEPHYS_SANITIZE MATCHES "^(address|undefined|thread)$")
    message(FATAL_ERROR "EDGEPHYS_SANITIZE must be address, undefined or thread")
  endif()
  add_compile_options(-fsanitize=${EDGEPHYS_SANITIZE} -fno-omit-frame-pointer)
  add_link_options(-fsanitize=${EDGEPHYS_SANITIZE})
  if(EDGEPHYS_SANITIZE STREQUAL "undefined")
    add_compile_options(-fno-sanitize-recover=undefined)
  endif()
endif()

# edgephys_add_test(<name> SOURCES <files...> LIBS <targets...> [LABELS <labels...>])
# One GoogleTest executable; every TEST becomes its own CTest case (gtest_discover_tests).
function(edgephys_add_test name)
  cmake_parse_arguments(T "" "" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE ${T_LIBS} GTest::gtest GTest::gmock GTest::gtest_main)
  edgephys_set_options(${name})
  if(NOT T_LABELS)
    set(T_LABELS unit)
  endif()
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "${T_LABELS}" TIMEOUT 300)
endfunction()

option(EDGEPHYS_BUILD_FUZZ "Build libFuzzer targets (requires clang)" OFF)

# Container tests (tests/container_test.sh: podman build + run of the Dockerfile) are slow and
# need root; they are registered but DISABLED unless this is ON.
option(EDGEPHYS_CONTAINER_TESTS "Enable the podman image build-and-run test (label container)" OFF)
option(EDGEPHYS_SOAK_TESTS "Enable the 10-minute soak test (label soak; scripts/soak.sh)" OFF)
