# geotraj_slow_tests(LABELS <labels> TESTS <name>...): gives tests that gtest_discover_tests
# found (NAME as ctest lists it) the labels <labels> and `slow`. `make sanitize` leaves slow
# tests out (ctest -LE slow): each takes a minute or more in a Release build, and what they
# reach runs under the sanitizers in other tests too.
#
# gtest_discover_tests cannot do it: a list in its PROPERTIES is split (LABELS "a;slow"
# becomes LABELS a and a property named slow). The labels are set instead by a file that
# ctest reads after the discovered tests' own (ctest knows set_tests_properties there, not
# set_property, hence the labels given again); a name that no longer exists is an error
# there, so a renamed test cannot lose its label unseen.
function(geotraj_slow_tests)
  cmake_parse_arguments(arg "" "" "LABELS;TESTS" ${ARGN})
  set(labels ${arg_LABELS} slow)
  set(file "${CMAKE_CURRENT_BINARY_DIR}/slow_tests.cmake")
  set(text "")
  foreach(name IN LISTS arg_TESTS)
    string(APPEND text "set_tests_properties([==[${name}]==] PROPERTIES LABELS \"${labels}\")\n")
  endforeach()
  file(WRITE "${file}" "${text}")
  set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES "${file}")
endfunction()
