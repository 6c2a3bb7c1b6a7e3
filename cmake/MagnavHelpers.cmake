# Shared build settings and one helper per kind of target, so every module is
# built the same way (warnings, sanitizers, namespaced alias).

add_library(magnav_warnings INTERFACE)
target_compile_options(magnav_warnings INTERFACE -Wall -Wextra -Wpedantic
  $<$<BOOL:${MAGNAV_WERROR}>:-Werror>)
if(MAGNAV_SANITIZE)
  target_compile_options(magnav_warnings INTERFACE -fsanitize=address,undefined -fno-omit-frame-pointer
    -fno-sanitize-recover=undefined)
  target_link_options(magnav_warnings INTERFACE -fsanitize=address,undefined)
  # Eigen switches to its own aligned malloc under ASan (__SANITIZE_ADDRESS__),
  # while Debian's Ceres was built without it: matrices allocated on one side
  # and freed on the other would then mismatch. Keep glibc's malloc on both.
  target_compile_definitions(magnav_warnings INTERFACE EIGEN_MALLOC_ALREADY_ALIGNED=1)
  # Fast DDS 2.9.1 itself deletes an RTPSReader through a base of another size
  # (reported inside libfastrtps, not in magnav): silence that one check.
  set(MAGNAV_TEST_ENV "ASAN_OPTIONS=new_delete_type_mismatch=0")
elseif(MAGNAV_TSAN)
  # (The flags are set for every target in CMakeLists.txt.) Any report fails
  # the test, the services it starts inherit the options.
  set(MAGNAV_TEST_ENV
    "TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:suppressions=${PROJECT_SOURCE_DIR}/scripts/tsan.supp")
endif()

# magnav_library(<name> SOURCES ... DEPS ...) -> target magnav_<name>, alias magnav::<name>.
# Public headers live in <module>/include/magnav/<name>/.
function(magnav_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(magnav_${name} ${ARG_SOURCES})
  add_library(magnav::${name} ALIAS magnav_${name})
  target_include_directories(magnav_${name} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>)
  target_link_libraries(magnav_${name} PUBLIC ${ARG_DEPS} PRIVATE magnav_warnings ${ARG_PRIVATE_DEPS})
  set_target_properties(magnav_${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
endfunction()

# magnav_test(<name> SOURCES ... DEPS ... [LABELS ...]) -> a GoogleTest executable
# registered with CTest (one CTest entry per TEST()).
function(magnav_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} magnav_test_support GTest::gtest GTest::gtest_main
    magnav_warnings)
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 120)
  endif()
  # Test data is found through a path compiled into magnav_test_support
  # ($MAGNAV_TEST_DATA overrides it). One ENVIRONMENT entry at most: a list
  # would be split into separate properties by gtest_discover_tests.
  set(env_props)
  if(MAGNAV_TEST_ENV)
    set(env_props ENVIRONMENT "${MAGNAV_TEST_ENV}")
  endif()
  gtest_discover_tests(${name}
    DISCOVERY_TIMEOUT 60
    PROPERTIES LABELS "${ARG_LABELS}" TIMEOUT ${ARG_TIMEOUT} ${env_props})
endfunction()

# magnav_service_test(<name> SERVICE <target> SOURCES ... DEPS ... LABELS <label>):
# a test that starts the service executable; its path is MAGNAV_SERVICE_BIN.
function(magnav_service_test name)
  cmake_parse_arguments(ARG "" "SERVICE;LABELS" "SOURCES;DEPS" ${ARGN})
  magnav_test(${name} SOURCES ${ARG_SOURCES} DEPS ${ARG_DEPS} magnav::dds LABELS ${ARG_LABELS} TIMEOUT 180)
  target_compile_definitions(${name} PRIVATE MAGNAV_SERVICE_BIN="$<TARGET_FILE:${ARG_SERVICE}>")
  add_dependencies(${name} ${ARG_SERVICE})
  # A stock-QoS driver in front of the service (tests/support/stock_relay.h),
  # where Cyclone DDS was found (tests/interop defines the target first).
  get_property(peer GLOBAL PROPERTY MAGNAV_CYCLONE_PEER_TARGET)
  if(peer)
    target_compile_definitions(${name} PRIVATE MAGNAV_CYCLONE_PEER="$<TARGET_FILE:${peer}>"
      MAGNAV_CYCLONE_CONFIG="${PROJECT_SOURCE_DIR}/config/cyclonedds_loopback.xml")
    add_dependencies(${name} ${peer})
  endif()
endfunction()

# A module's DDS service (the only part of a module that includes DDS
# headers): its node as a library magnav::<module>_service (sources
# service/<node>.cc, headers in service/) over the module's library, the
# DDS adapter and the module's message conversions (magnav::dds_<module>,
# dds/CMakeLists.txt), and its thin main as the executable.
#   magnav_service(MODULE inversion EXECUTABLE magnav-inverter NODE inverter_node)
function(magnav_service)
  cmake_parse_arguments(ARG "" "MODULE;EXECUTABLE;NODE" "" ${ARGN})
  set(lib magnav_${ARG_MODULE}_service)
  add_library(${lib} STATIC service/${ARG_NODE}.cc)
  add_library(magnav::${ARG_MODULE}_service ALIAS ${lib})
  target_include_directories(${lib} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/service)
  target_link_libraries(${lib} PUBLIC magnav::${ARG_MODULE} magnav::dds magnav::dds_${ARG_MODULE} PRIVATE spdlog::spdlog magnav_warnings)
  add_executable(${ARG_EXECUTABLE} service/main.cc)
  target_link_libraries(${ARG_EXECUTABLE} PRIVATE magnav::${ARG_MODULE}_service magnav::cli spdlog::spdlog magnav_warnings)
endfunction()
