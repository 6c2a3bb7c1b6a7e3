// Checks of an options struct's IsValid(std::string*): one field set wrong
// is refused, and the reason names the field.
#pragma once

#include <string>

#include <gtest/gtest.h>

namespace magnav::testing {

// `Options{}` with `edit` applied is refused by IsValid, with `field` in the reason.
template <class Options, class Edit>
void ExpectRefused(Edit edit, const std::string& field) {
  Options o{};
  edit(o);
  std::string why;
  EXPECT_FALSE(o.IsValid(&why)) << field << " accepted";
  EXPECT_NE(why.find(field), std::string::npos) << "the reason '" << why << "' does not name " << field;
}

}  // namespace magnav::testing
