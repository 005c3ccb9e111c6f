// Counts the program's heap allocations, so that tests can assert that a hot loop makes
// none. Link allocation_counter.cpp (it replaces the global operator new) into the test.
#pragma once

namespace geotraj::testing {

/// Number of calls to the global operator new so far.
long allocation_count();

}  // namespace geotraj::testing
