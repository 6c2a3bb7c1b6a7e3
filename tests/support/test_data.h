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
// DDS domain id of this test process (10 + pid % 200), as Fast DDS's blackbox
// tests derive theirs: concurrent test processes rarely share a domain.
int TestDomainId();

// A fresh temporary directory for one test (removed by the OS on reboot).
std::string TempDir();

}  // namespace magnav::testing
