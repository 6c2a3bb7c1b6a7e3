// Conversion between the IDL topic types and the core structs the libraries
// use. Pure value copies; no validation (the libraries' gates judge samples).
#pragma once

#include "magnav/core/gradiometer.h"
#include "magnav/dds/topics.h"

namespace magnav::dds {

GradiometerSample FromMsg(const msg::GradiometerSample& m);
msg::GradiometerSample ToMsg(const GradiometerSample& s, std::uint64_t seq);

}  // namespace magnav::dds
