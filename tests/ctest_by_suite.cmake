# Read by ctest (a TEST_INCLUDE_FILES script): adds one test per gtest suite
# of a test program instead of one per test, when PROPCAM_CTEST_BY_SUITE is
# on (the default). A test program starts with about 260 shared libraries
# (OpenImageIO's and OpenCV's): a start costs about 0.4 s of CPU in Release
# and 1 s under AddressSanitizer, more than most tests do; a suite runs its
# tests in one process. Tests named slow stay tests of their own, with the
# label slow_under_asan. A suite's COST is its number of tests, so that on a
# clean clone (no timings recorded) ctest -j starts the big suites first.
# Called with the program's path, its labels and its slow tests.
function(propcam_add_suite_tests exe labels slow)
  get_filename_component(_name "${exe}" NAME)
  if(NOT EXISTS "${exe}")
    add_test("${_name}_NOT_BUILT" "${exe}")
    return()
  endif()
  execute_process(COMMAND "${exe}" --gtest_list_tests OUTPUT_VARIABLE _listing RESULT_VARIABLE _rc TIMEOUT 60)
  if(NOT _rc EQUAL 0)
    add_test("${_name}_LISTING_FAILED" "${exe}" --gtest_list_tests)
    return()
  endif()
  get_filename_component(_dir "${exe}" DIRECTORY)
  string(REPLACE "\n" ";" _lines "${_listing}")
  set(_suites)
  foreach(_line IN LISTS _lines)
    string(REGEX REPLACE " *#.*$" "" _line "${_line}")  # a parameter's description
    if(_line MATCHES "^([^ ]+)\\.$")
      set(_suite "${CMAKE_MATCH_1}")
      list(APPEND _suites "${_suite}")
      set(_slow_in_${_suite})
      set(_fast_in_${_suite} 0)
    elseif(_line MATCHES "^  ([^ ]+)$" AND DEFINED _suite)
      set(_test "${_suite}.${CMAKE_MATCH_1}")
      list(FIND slow "${_test}" _at)  # ctest reads this with old policies: no IN_LIST
      if(_at GREATER -1)
        list(APPEND _slow_in_${_suite} "${_test}")
      else()
        math(EXPR _fast_in_${_suite} "${_fast_in_${_suite}} + 1")
      endif()
    endif()
  endforeach()
  foreach(_suite IN LISTS _suites)
    if(_fast_in_${_suite} GREATER 0)
      set(_filter "${_suite}.*")
      if(_slow_in_${_suite})
        list(JOIN _slow_in_${_suite} ":" _excluded)
        string(APPEND _filter "-${_excluded}")
      endif()
      add_test("${_suite}.*" "${exe}" "--gtest_filter=${_filter}")
      set_tests_properties("${_suite}.*" PROPERTIES LABELS "${labels}" TIMEOUT 1800 WORKING_DIRECTORY "${_dir}"
        COST ${_fast_in_${_suite}})
    endif()
    foreach(_test IN LISTS _slow_in_${_suite})
      add_test("${_test}" "${exe}" "--gtest_filter=${_test}")
      set_tests_properties("${_test}" PROPERTIES LABELS "${labels};slow_under_asan" TIMEOUT 900 COST 20
        WORKING_DIRECTORY "${_dir}" SKIP_REGULAR_EXPRESSION "\\[  SKIPPED \\]")
    endforeach()
  endforeach()
endfunction()
