// One path helper for test data (as Ceres' test_util): the reference files
// copied from ../shared/reference live in tests/data/reference/ with their README.
#pragma once

#include <string>

namespace magnav::testing {

// Directory of tests/data (from $MAGNAV_TEST_DATA, set by CTest, else the
// source tree path compiled in).
std::string TestDataDir();
// Path of a reference file, e.g. ReferencePath("dipole_cases.csv").
std::string ReferencePath(const std::string& name);
// DDS domain id of this test process: an even domain in [10, 228] claimed
// with a lock file for the process's lifetime (its odd successor comes with
// it, for a relay's input), shared with the test scripts' dds_test_setup
// (tests/support/dds_test_lib.sh): concurrent test processes never share one.
// Throws when all 110 are held.
int TestDomainId();

// A fresh temporary directory for one test (removed by the OS on reboot).
std::string TempDir();

}  // namespace magnav::testing
