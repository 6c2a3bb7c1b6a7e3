// The EKF fed as a stream (what magnav-localizer runs, and what RunEkf runs
// over a whole file): samples and fixes arrive one by one, possibly a little
// out of order across sensors and the GNSS; each is checked at the door
// (InputGate), held in a short reorder buffer, and handed to the EKF in time
// order (fixes before samples at equal times, then arrival order). The vessel
// is started from the GNSS fixes of the first `init_window_s` (ekf.h
// InitialVesselFromGnss). Nothing that fails a check reaches the EKF.
//
// Frames and units: types.h. Not thread-safe.
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <tuple>
#include <variant>
#include <vector>

#include "magnav/localizer/ekf.h"
#include "magnav/localizer/input.h"
#include "magnav/localizer/options.h"
#include "magnav/localizer/types.h"

namespace magnav::localizer {

struct StreamOptions {
  // An item is handed to the EKF once an item this much newer (sample time,
  // s) has arrived, or at Flush. Infinity = only at Flush.
  double reorder_delay_s = 1.0;
  // The vessel is started from the fixes within this many s of the first
  // item; the stream is held until that window (plus the reorder delay) has
  // passed.
  double init_window_s = 10.0;

  bool IsValid(std::string* error) const;
};

class StreamingLocalizer {
 public:
  // Throws InputError if the options are invalid or no sensor is given.
  StreamingLocalizer(const Vessel& vessel, const std::vector<SensorPrior>& sensors, const LocalizerOptions& options,
                     const StreamOptions& stream = {});
  ~StreamingLocalizer();

  // kOk: accepted (buffered). Anything else: refused, state untouched:
  // non-finite, unknown sensor, older than the same stream's last sample, or
  // older than what the EKF has already consumed (kTimeBackwards).
  SampleCheck Add(const MagSample& sample);
  SampleCheck Add(const GnssFix& fix);
  // Hands everything buffered to the EKF (end of stream).
  void Flush();

  bool initialized() const { return ekf_ != nullptr; }
  // Time of the EKF (s); −inf before it starts.
  double time() const;
  // Current sensor estimates with covariance; with `bounds`, the Cramér–Rao
  // bounds along the filtered trajectory of everything consumed so far
  // (costs a sparse solve over that trajectory). Empty before the start.
  std::vector<SensorEstimate> Estimates(bool bounds) const;
  // Everything as RunEkf returns it (estimates, bounds, trajectory, summary).
  Localization Result() const;

  std::uint64_t consumed() const { return consumed_; }   // items the EKF took
  std::uint64_t late() const { return late_; }           // refused: older than consumed
  std::uint64_t failed() const { return failed_; }       // EKF refused (e.g. singular, time 1e300 s ahead)
  std::uint64_t rejected() const { return rejected_; }   // refused by the EKF's NIS gate (outliers)
  std::uint64_t dropped_before_start() const { return dropped_before_start_; }

 private:
  using Item = std::variant<MagSample, GnssFix>;
  using Key = std::tuple<double, int, std::uint64_t>;  // time, 0 = fix / 1 = sample, arrival
  SampleCheck Buffer(double t_s, int kind, Item item);
  void Release(bool all);
  bool TryStart(bool final);
  void Consume(const Item& item);

  Vessel vessel_;
  std::vector<SensorPrior> sensors_;
  LocalizerOptions options_;
  StreamOptions stream_;
  InputGate gate_;
  std::map<Key, Item> pending_;
  std::uint64_t arrivals_ = 0;
  double newest_t_ = -std::numeric_limits<double>::infinity();
  double consumed_until_ = -std::numeric_limits<double>::infinity();
  std::unique_ptr<LocalizerEkf> ekf_;
  // What the EKF consumed, for the bounds: a pass and the state per epoch.
  Pass pass_;
  std::vector<double> epoch_t_;
  std::vector<VesselVector> trajectory_;
  std::uint64_t consumed_ = 0, late_ = 0, failed_ = 0, rejected_ = 0, dropped_before_start_ = 0;
};

}  // namespace magnav::localizer
