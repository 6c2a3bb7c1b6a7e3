// The door's limits: the largest magnitude of each quantity any reader
// (files, and the wire where the quantity travels) accepts, each with the
// reason it is where it is. One table for the whole project
// (docs/RELIABILITY.md "Limits" lists it); beyond a limit a value is not a
// reading (1e308, a unit written for another, a header that lies) and the
// reader stops with "FILE:LINE: column 'NAME': V UNIT is out of range
// (|value| > LIMIT UNIT; WHY)".
//
// A site may set its own limits (SetSiteLimits / LoadSiteLimits: `--limits
// FILE` on `magnav` and every service), e.g. a SQUID array's tensor range
// far below the fluxgate-safe default. Every check goes through MaxAbs /
// WithinLimit, so the site's value holds at every door. Set them once at
// start, before any reader runs.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace magnav {

struct Limit {
  const char* quantity;
  double max_abs;  // the default: largest |value| accepted unless the site says otherwise
  const char* unit;
  const char* why;
  const char* key;  // its name in a site limits file (LoadSiteLimits)
  int id;           // its index in kLimits
};

// Gradiometer samples (core/gradiometer.h, the localizer's files, the wire).
inline constexpr Limit kLimitPosition{"position", 1e7, "m", "a position in km or beyond the Earth", "position_m", 0};
inline constexpr Limit kLimitB{"magnetic field B", 1.0, "T",
                               "B in nT or uT written as T? (the Earth's field is 5e-5 T)", "B_T", 1};
inline constexpr Limit kLimitT{"gradient tensor element", 10.0, "T/m", "a gradient in nT/m written as T/m?", "T_Tpm", 2};
// Map matching (mapmatch/: map files of every format and map paths).
inline constexpr Limit kLimitMapValue{
    "map or path field value", 1e6, "nT",
    "more than any main field (< 7e4 nT) or crustal anomaly (< 2e5 nT): not a reading in nT", "map_value_nT", 3};
inline constexpr Limit kLimitLatitude{"latitude", 90.0, "deg", "a latitude beyond a pole", "latitude_deg", 4};
inline constexpr Limit kLimitLongitude{"longitude", 360.0, "deg",
                                       "beyond one turn either way: not a longitude in degrees", "longitude_deg", 5};
// Raster map headers: the grid a header claims, refused before anything is
// allocated (8 bytes per cell per layer, twice while read: 1e8 cells = 1.6 GB).
inline constexpr Limit kLimitMapCells{"map grid cells (rows x columns)", 1e8, "cells",
                                      "a 100 m grid of the whole Earth has 5e10: no map this project reads "
                                      "comes near 1e8, and a larger claim is a corrupt or hostile header", "map_cells", 6};
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
inline constexpr Limit kLimitTime{"time", 1e10, "s", "317 years: Unix and GPS seconds fit; 1e300 is not a time", "time_s", 7};
inline constexpr Limit kLimitTimeStep{"time step within a stream", 3600.0, "s",
                                      "samples come seconds apart: a stamp in ns, from another clock, or 2^64-1", "time_step_s", 8};
inline constexpr Limit kLimitSeqStep{"sequence number step within a stream", 1e6, "",
                                     "a million samples skipped at once is a corrupt seq (e.g. 10^18), not loss", "seq_step", 9};

inline constexpr std::array<Limit, 10> kLimits = {kLimitPosition,  kLimitB,        kLimitT,    kLimitMapValue,
                                                  kLimitLatitude,  kLimitLongitude, kLimitMapCells, kLimitTime,
                                                  kLimitTimeStep, kLimitSeqStep};

// The limit in force: the site's (SetSiteLimits) or the default.
double MaxAbs(const Limit& limit);
// Why the limit in force is where it is: the default's reason, or "site
// limit from SOURCE".
std::string LimitWhy(const Limit& limit);

// Whether |value| is within the limit in force (false for NaN).
inline bool WithinLimit(const Limit& limit, double value) {
  const double m = MaxAbs(limit);
  return value >= -m && value <= m;
}

// "1e+308 nT is out of range (|value| > 1e+06 nT; WHY)": what follows
// "FILE:LINE: column 'NAME': " in a reader's error.
std::string OutOfRange(const Limit& limit, double value);

// A site's limits: (key, value) pairs, keys as in Limit::key, each value
// finite and > 0 (it may be tighter or looser than the default); limits not
// named keep their default. Replaces any earlier site limits. `source` names
// them in messages (a file). Throws InputError naming a bad key or value, and
// then changes nothing.
void SetSiteLimits(const std::vector<std::pair<std::string, double>>& values, const std::string& source);
// Reads a site limits file: lines "key = value" (TOML/INI: '#' or ';'
// comments, blank lines, an optional "[limits]" section header), then
// SetSiteLimits. Throws InputError "FILE:LINE: ..." on anything else.
void LoadSiteLimits(const std::string& path);
// Back to the defaults.
void ResetSiteLimits();
// "T_Tpm = 1e-05 (site limit from FILE; default 10)" per site limit, for logs; empty when none.
std::vector<std::string> DescribeSiteLimits();

}  // namespace magnav
