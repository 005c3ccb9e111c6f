// Where this build put what the tests run or read: the daemon, the CLI and the source tree's
// fixtures. The absolute paths live in one generated source (tests/CMakeLists.txt), so that
// the test sources compile the same in any clone folder and the compiler cache serves them.
#pragma once

namespace geotraj::testing::build_paths {

const char* geotrajd();       ///< the geotrajd binary ("" in a build without the server)
const char* cli();            ///< the geotraj CLI binary ("" in a build without the server)
const char* examples_dir();   ///< client/grpcurl: the example requests
const char* urdf_fixtures();  ///< tests/planner/urdf: URDF documents as shipped
const char* source_dir();     ///< the source tree's root

}  // namespace geotraj::testing::build_paths
