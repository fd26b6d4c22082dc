# Run by pcr_test (cmake/PcrHelpers.cmake) after a GoogleTest executable is linked: lists its
# tests (--gtest_list_tests) and writes TEST_FILE, which CTest includes, with one CTest test per
# GoogleTest suite (the executable with --gtest_filter=SUITE.*).
#
# Variables: TEST_EXECUTABLE, TEST_FILE, TEST_ENVIRONMENT (NAME=VALUE), TEST_COSTS (a list of
# SUITE=SECONDS: the suites that run longest, started first by `ctest -j` where it has no timings
# of its own yet, as on a fresh clone).
execute_process(COMMAND "${TEST_EXECUTABLE}" --gtest_list_tests
                OUTPUT_VARIABLE listing ERROR_VARIABLE errors RESULT_VARIABLE rc TIMEOUT 60)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${TEST_EXECUTABLE} --gtest_list_tests failed (${rc}): ${errors}")
endif()

# A suite line is unindented and ends with '.' (a typed suite's "  # TypeParam = ..." after it);
# its tests follow, indented (and are not needed here).
string(REPLACE ";" "\\;" listing "${listing}")
string(REPLACE "\n" ";" lines "${listing}")
set(suites "")
foreach(line IN LISTS lines)
  if(line MATCHES "^([^ #][^ ]*)\\.( +#.*)?$")
    list(APPEND suites "${CMAKE_MATCH_1}")
  endif()
endforeach()
if(NOT suites)
  message(FATAL_ERROR "${TEST_EXECUTABLE} lists no tests:\n${listing}")
endif()

set(text "# Generated from ${TEST_EXECUTABLE} --gtest_list_tests by PcrGTestSuites.cmake.\n")
foreach(suite IN LISTS suites)
  # A suite all of whose tests skipped (GoogleTest: "[  PASSED  ] 0 tests.") is reported as
  # skipped; one with some skipped passes, and its output names them.
  string(APPEND text
         "add_test([==[${suite}]==] [==[${TEST_EXECUTABLE}]==] [==[--gtest_filter=${suite}.*]==])\n"
         "set_tests_properties([==[${suite}]==] PROPERTIES ENVIRONMENT [==[${TEST_ENVIRONMENT}]==]"
         " SKIP_REGULAR_EXPRESSION [==[\\[  PASSED  \\] 0 tests\\.]==])\n")
  foreach(entry IN LISTS TEST_COSTS)
    if(entry MATCHES "^${suite}=([0-9.]+)$")
      string(APPEND text "set_tests_properties([==[${suite}]==] PROPERTIES COST ${CMAKE_MATCH_1})\n")
    endif()
  endforeach()
endforeach()
file(WRITE "${TEST_FILE}" "${text}")
