# Helpers shared by every module's CMakeLists.txt.

# subslam_add_module(NAME SOURCES a.cc b.cc DEPS subslam::core Eigen3::Eigen ...
#                    [PRIVATE_DEPS ...])
# Creates the static library subslam_<NAME>, alias subslam::<NAME>, whose public
# headers live in <module>/include/subslam/<NAME>/ and are installed.
function(subslam_add_module NAME)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(subslam_${NAME} ${ARG_SOURCES})
  add_library(subslam::${NAME} ALIAS subslam_${NAME})
  set_target_properties(subslam_${NAME} PROPERTIES EXPORT_NAME ${NAME}
                        POSITION_INDEPENDENT_CODE ON)
  target_compile_features(subslam_${NAME} PUBLIC cxx_std_20)
  target_compile_options(subslam_${NAME} PRIVATE -Wall -Wextra)
  target_include_directories(subslam_${NAME} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(subslam_${NAME} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  # Eigen's memory layout is part of the library's ABI. By default it follows the
  # instruction set: objects aligned to 16 bytes and plain malloc with SSE; 32 or 64
  # bytes and Eigen's own allocator with AVX or AVX-512, or under AddressSanitizer.
  # Code built differently on the other side corrupts the heap as soon as an Eigen
  # object crosses over. So the layout is pinned, and handed on to every user of these
  # targets, whatever -march either side is built with: fixed-size objects aligned to
  # 16 bytes (their layout as with SSE); heap blocks always from Eigen's own allocator,
  # 64-byte aligned (the AVX-512 packet; its realloc moves data by the alignment it was
  # built with, so every side must use the same). -march=native stays a pure speed
  # choice (no measurable cost of the pinning: bench/RESULTS.md).
  target_compile_definitions(subslam_${NAME} PUBLIC EIGEN_MAX_ALIGN_BYTES=64 EIGEN_MAX_STATIC_ALIGN_BYTES=16
                             EIGEN_MALLOC_ALREADY_ALIGNED=0)
  if(SUBSLAM_SANITIZER_FLAGS)  # users of a sanitized build link its runtime
    target_link_options(subslam_${NAME} INTERFACE ${SUBSLAM_SANITIZER_FLAGS})
  endif()
  install(TARGETS subslam_${NAME} EXPORT subslamTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR}/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
endfunction()

# subslam_add_test(NAME SOURCES a_test.cc DEPS subslam::core ...)
# One GoogleTest executable registered with CTest through gtest_discover_tests.
function(subslam_add_test NAME)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${NAME} ${ARG_SOURCES})
  target_compile_options(${NAME} PRIVATE -Wall -Wextra)
  target_include_directories(${NAME} PRIVATE ${PROJECT_SOURCE_DIR}/tests)
  target_compile_definitions(${NAME} PRIVATE
    SUBSLAM_VICTORIA_PARK_DIR="${SUBSLAM_VICTORIA_PARK_DIR}")
  target_link_libraries(${NAME} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  gtest_discover_tests(${NAME} DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "${ARG_LABELS}")
endfunction()
