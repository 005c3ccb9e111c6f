# geotraj_label_tests(FILE <stem> LABELS <labels> TESTS <name>...): gives tests that
# gtest_discover_tests found (NAME as ctest lists it) the labels <labels>, replacing theirs.
#
# gtest_discover_tests cannot do it: a list in its PROPERTIES is split (LABELS "a;slow"
# becomes LABELS a and a property named slow). The labels are set instead by a file that
# ctest reads after the discovered tests' own (ctest knows set_tests_properties there, not
# set_property, hence the labels given again). ctest ignores a name it does not know: the
# test `ctest.labelled_tests_exist` (cmake/check_labelled_tests.cmake) fails when a listed
# name is not a test, so that a renamed test cannot lose its label unseen. One file per
# <stem> and directory.
function(geotraj_label_tests)
  cmake_parse_arguments(arg "" "FILE" "LABELS;TESTS" ${ARGN})
  geotraj_discovered_test_properties(FILE ${arg_FILE} PROPERTY LABELS VALUE ${arg_LABELS} TESTS ${arg_TESTS})
endfunction()

# geotraj_discovered_test_properties(FILE <stem> PROPERTY <p> VALUE <v> TESTS <name>...): the
# file above, for any one property; each listed name is checked by ctest.labelled_tests_exist.
function(geotraj_discovered_test_properties)
  cmake_parse_arguments(arg "" "FILE;PROPERTY" "VALUE;TESTS" ${ARGN})  # VALUE: a list for LABELS
  set(file "${CMAKE_CURRENT_BINARY_DIR}/${arg_FILE}.cmake")
  set(text "")
  foreach(name IN LISTS arg_TESTS)
    string(APPEND text "set_tests_properties([==[${name}]==] PROPERTIES ${arg_PROPERTY} \"${arg_VALUE}\")\n")
  endforeach()
  file(WRITE "${file}" "${text}")
  set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES "${file}")
  set_property(GLOBAL APPEND PROPERTY GEOTRAJ_LABELLED_TESTS ${arg_TESTS})
endfunction()

# The test that every name given to geotraj_label_tests is a test ctest knows. Call once,
# after every directory's tests are added.
function(geotraj_check_labelled_tests)
  get_property(names GLOBAL PROPERTY GEOTRAJ_LABELLED_TESTS)
  set(list "${CMAKE_BINARY_DIR}/labelled_tests.txt")
  string(REPLACE ";" "\n" lines "${names}")
  file(WRITE "${list}" "${lines}\n")
  add_test(NAME ctest.labelled_tests_exist
           COMMAND ${CMAKE_COMMAND} -DCTEST=${CMAKE_CTEST_COMMAND} -DBUILD_DIR=${CMAKE_BINARY_DIR} -DNAMES=${list}
                   -P ${PROJECT_SOURCE_DIR}/cmake/check_labelled_tests.cmake)
  set_tests_properties(ctest.labelled_tests_exist PROPERTIES LABELS unit)
endfunction()

# geotraj_slow_tests(LABELS <labels> TESTS <name>...): <labels> and `slow`. `make sanitize`
# leaves slow tests out (ctest -LE): each takes a minute or more in a Release build, and what
# they reach runs under the sanitizers in other tests too.
function(geotraj_slow_tests)
  cmake_parse_arguments(arg "" "" "LABELS;TESTS" ${ARGN})
  geotraj_label_tests(FILE slow_tests LABELS ${arg_LABELS} slow TESTS ${arg_TESTS})
endfunction()

# geotraj_heavy_tests(LABELS <labels> TESTS <name>...): <labels> and `heavy`. `make sanitize`
# leaves these out too: numerical property tests of many random cases that take 20 s or more
# under the sanitizers (seconds in Release, where `make test` runs them), whose code the
# other tests reach under the sanitizers with fewer cases.
function(geotraj_heavy_tests)
  cmake_parse_arguments(arg "" "" "LABELS;TESTS" ${ARGN})
  geotraj_label_tests(FILE heavy_tests LABELS ${arg_LABELS} heavy TESTS ${arg_TESTS})
endfunction()

# geotraj_first_tests(TESTS <name>...): tests that `ctest -j` starts before the others. ctest
# orders a parallel run by the times it measured before, and a fresh clone (CI) has none: a
# test of a minute that starts last then runs alone at the end. These are the longest under
# the sanitizers or in Release (`ctest` prints each one's time).
function(geotraj_first_tests)
  cmake_parse_arguments(arg "" "" "TESTS" ${ARGN})
  geotraj_discovered_test_properties(FILE first_tests PROPERTY COST VALUE 1000 TESTS ${arg_TESTS})
endfunction()
