// The fuzz entry points (docs/RELIABILITY.md, "Fuzzing"): one per kind of
// input, each taking raw bytes and running them through the same readers and
// conversions the programs use. A clean refusal (InputError, CLI11's
// ParseError: what the programs catch and report with exit code 2) returns
// normally; anything else — another exception, a crash, a sanitizer report —
// is a defect. Each is called by a libFuzzer target (fuzz_main.cc, clang,
// scripts/fuzz) and by tests/fuzz/fuzz_regression_test.cc, which replays the
// inputs in tests/data/fuzz/<target>/ in the normal build.
#pragma once

#include <cstddef>
#include <cstdint>

namespace magnav::fuzz {

// CSV files: CsvTable::Parse and every accessor, then the typed readers on
// the same bytes as a file: gradiometer passes (ReadGradiometerFile, two
// column sets), map-matching paths (ReadMatchPath), the localiser's
// deployment, measurements and GNSS files (ReadDeploymentFile, ReadPassFiles
// with well-formed companions).
void FuzzCsv(const std::uint8_t* data, std::size_t size);

// Map files: ReadGeoGridCsv (one and two layers) and ReadGeoGridXyz; a map
// that is read is then sampled (nodes, cell centres, outside, edges).
void FuzzMap(const std::uint8_t* data, std::size_t size);

// A service's --config file (TOML/INI) through StrictConfig, with the options
// the services share (B0, X,Y,Z lists, tracker and particle-filter flags,
// numbers, strings, vectors, flags).
void FuzzConfig(const std::uint8_t* data, std::size_t size);

// DDS samples at the door (needs MAGNAV_BUILD_DDS): the first byte picks the
// topic type (byte % 7: gradiometer, magnetometer, vessel navigation, dipole
// fix, track, sensor position, map fix); the rest is a CDR payload
// deserialised by the type support the services register (TopicTraits), then
// for the first three converted (FromMsg/ToMsg, AnomalyOf, InsNavMsg) and
// checked (CheckSample, SampleDoor).
void FuzzDdsConvert(const std::uint8_t* data, std::size_t size);

// MCAP recordings: the reader (tools/mcap, mcap::ReadBytes) with every
// message's channel and schema checked; a cut file is read with a warning,
// anything invalid refused with InputError.
void FuzzMcap(const std::uint8_t* data, std::size_t size);

}  // namespace magnav::fuzz
