// The door's limits: the largest magnitude of each quantity any reader
// (files, and the wire where the quantity travels) accepts, each with the
// reason it is where it is. One table for the whole project
// (docs/RELIABILITY.md "Limits" lists it); beyond a limit a value is not a
// reading (1e308, a unit written for another, a header that lies) and the
// reader stops with "FILE:LINE: column 'NAME': V UNIT is out of range
// (|value| > LIMIT UNIT; WHY)".
#pragma once

#include <array>
#include <cstddef>
#include <string>

namespace magnav {

struct Limit {
  const char* quantity;
  double max_abs;  // largest |value| accepted
  const char* unit;
  const char* why;
};

// Gradiometer samples (core/gradiometer.h, the localizer's files, the wire).
inline constexpr Limit kLimitPosition{"position", 1e7, "m", "a position in km or beyond the Earth"};
inline constexpr Limit kLimitB{"magnetic field B", 1.0, "T",
                               "B in nT or uT written as T? (the Earth's field is 5e-5 T)"};
inline constexpr Limit kLimitT{"gradient tensor element", 10.0, "T/m", "a gradient in nT/m written as T/m?"};
// Map matching (mapmatch/: map files of every format and map paths).
inline constexpr Limit kLimitMapValue{
    "map or path field value", 1e6, "nT",
    "more than any main field (< 7e4 nT) or crustal anomaly (< 2e5 nT): not a reading in nT"};
inline constexpr Limit kLimitLatitude{"latitude", 90.0, "deg", "a latitude beyond a pole"};
inline constexpr Limit kLimitLongitude{"longitude", 360.0, "deg",
                                       "beyond one turn either way: not a longitude in degrees"};
// Raster map headers: the grid a header claims, refused before anything is
// allocated (8 bytes per cell per layer, twice while read: 1e8 cells = 1.6 GB).
inline constexpr Limit kLimitMapCells{"map grid cells (rows x columns)", 1e8, "cells",
                                      "a 100 m grid of the whole Earth has 5e10: no map this project reads "
                                      "comes near 1e8, and a larger claim is a corrupt or hostile header"};
// A text raster (ESRI .asc, ...) holds at least this many bytes per cell (a
// digit and a separator): a header claiming more cells than that is refused.
inline constexpr double kMinTextBytesPerCell = 2.0;

// Time. A pass or a live stream is minutes to months long; its samples come
// seconds apart. Files: |t| beyond kLimitTime is refused outright, and a row
// more than kLimitTimeStep after the previous row of its stream. On the wire
// time has no absolute scale (a driver's clock may start anywhere), so the
// rule there is relative (dds/stamp_guard.h): a stamp more than
// kLimitTimeStep from its stream's last one, or a seq jump beyond
// kLimitSeqStep, is held as suspect until the next sample confirms it.
inline constexpr Limit kLimitTime{"time", 1e10, "s", "317 years: Unix and GPS seconds fit; 1e300 is not a time"};
inline constexpr Limit kLimitTimeStep{"time step within a stream", 3600.0, "s",
                                      "samples come seconds apart: a stamp in ns, from another clock, or 2^64-1"};
inline constexpr Limit kLimitSeqStep{"sequence number step within a stream", 1e6, "",
                                     "a million samples skipped at once is a corrupt seq (e.g. 10^18), not loss"};

inline constexpr std::array<Limit, 10> kLimits = {kLimitPosition,  kLimitB,        kLimitT,    kLimitMapValue,
                                                  kLimitLatitude,  kLimitLongitude, kLimitMapCells, kLimitTime,
                                                  kLimitTimeStep, kLimitSeqStep};

// The names the readers used before the table (kept: same values).
inline constexpr double kMaxAbsPosition_m = kLimitPosition.max_abs;
inline constexpr double kMaxAbsB_T = kLimitB.max_abs;
inline constexpr double kMaxAbsT_Tpm = kLimitT.max_abs;

// Whether |value| is within the limit (false for NaN).
inline bool WithinLimit(const Limit& limit, double value) {
  return value >= -limit.max_abs && value <= limit.max_abs;
}

// "1e+308 nT is out of range (|value| > 1e+06 nT; WHY)": what follows
// "FILE:LINE: column 'NAME': " in a reader's error.
std::string OutOfRange(const Limit& limit, double value);

}  // namespace magnav
