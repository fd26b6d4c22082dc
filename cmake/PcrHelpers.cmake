# pcr_layer(NAME DIR DEPS...): one static library per layer from every .cpp below DIR.
# New files are picked up on the next build (CONFIGURE_DEPENDS), so adding a source needs no edit here.
function(pcr_layer name dir)
  file(GLOB_RECURSE srcs CONFIGURE_DEPENDS "${CMAKE_CURRENT_SOURCE_DIR}/${dir}/*.cpp")
  if(NOT srcs)
    add_library(${name} INTERFACE)
    target_include_directories(${name} INTERFACE ${CMAKE_SOURCE_DIR}/src ${CMAKE_SOURCE_DIR}/include)
    target_link_libraries(${name} INTERFACE ${ARGN})
    return()
  endif()
  add_library(${name} STATIC ${srcs})
  target_include_directories(${name} PUBLIC ${CMAKE_SOURCE_DIR}/src ${CMAKE_SOURCE_DIR}/include)
  target_link_libraries(${name} PUBLIC ${ARGN})
  set_target_properties(${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  pcr_precompiled_headers(${name} library)
endfunction()

# pcr_test(NAME DIR LIBS...): one GoogleTest executable from every .cpp below tests/DIR, one CTest
# test per GoogleTest suite (PCR_CTEST_PER_SUITE) or per GoogleTest test.
function(pcr_test name dir)
  file(GLOB_RECURSE srcs CONFIGURE_DEPENDS "${CMAKE_SOURCE_DIR}/tests/${dir}/*.cpp")
  if(NOT srcs)
    return()
  endif()
  add_executable(${name} ${srcs})
  pcr_precompiled_headers(${name} test)
  target_link_libraries(${name} PRIVATE ${ARGN} pcr_test_support GTest::gtest GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE PCR_SHARED_DIR="${PCR_SHARED_DIR}"
                                             PCR_SOURCE_DIR="${CMAKE_SOURCE_DIR}")
  if(NOT PCR_CTEST_PER_SUITE)
    gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES ENVIRONMENT
                         "PCR_SHARED_DIR=${PCR_SHARED_DIR}")
    return()
  endif()
  # One CTest test per GoogleTest suite (cmake/PcrGTestSuites.cmake), listed after each link.
  set(suites_file "${CMAKE_CURRENT_BINARY_DIR}/${name}_suites.cmake")
  add_custom_command(
    TARGET ${name} POST_BUILD BYPRODUCTS "${suites_file}"
    COMMAND "${CMAKE_COMMAND}" -D "TEST_EXECUTABLE=$<TARGET_FILE:${name}>"
            -D "TEST_FILE=${suites_file}" -D "TEST_ENVIRONMENT=PCR_SHARED_DIR=${PCR_SHARED_DIR}"
            -D "TEST_COSTS=${PCR_CTEST_SUITE_COSTS}" -P "${CMAKE_SOURCE_DIR}/cmake/PcrGTestSuites.cmake"
    VERBATIM)
  set(include_file "${CMAKE_CURRENT_BINARY_DIR}/${name}_suites_include.cmake")
  file(WRITE "${include_file}"
       "if(EXISTS [==[${suites_file}]==])\n"
       "  include([==[${suites_file}]==])\n"
       "else()\n"
       "  add_test([==[${name}_NOT_BUILT]==] [==[${name}_NOT_BUILT]==])\n"
       "endif()\n")
  set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES "${include_file}")
endfunction()

# pcr_use_allocator(TARGET): an executable that runs whole sequences links jemalloc, when the
# build found it (PCR_HAVE_JEMALLOC), ahead of the C library so that it serves malloc and new.
function(pcr_use_allocator target)
  if(PCR_HAVE_JEMALLOC)
    target_link_libraries(${target} PRIVATE ${PCR_JEMALLOC_LIBRARY})
  endif()
endfunction()
