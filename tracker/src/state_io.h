// The tracker's pieces in a checkpoint payload (core/checkpoint.h fields):
// samples, epochs, fixes, window summaries and the options a checkpoint is
// made for. Doubles bit for bit. Internal to the tracker library.
#pragma once

#include <cstddef>
#include <deque>

#include "magnav/core/checkpoint.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker::internal {

// A count read back from a checkpoint is at most this (a corrupt length does not allocate).
inline constexpr std::size_t kMaxStateCount = std::size_t{1} << 24;

void Put(StateWriter& w, const GradiometerSample& s);
void Get(StateReader& r, GradiometerSample* s);
void Put(StateWriter& w, const Epoch& e);
void Get(StateReader& r, Epoch* e);
void Put(StateWriter& w, const DipoleFix& f);
void Get(StateReader& r, DipoleFix* f);
void Put(StateWriter& w, const Summary& s);
void Get(StateReader& r, Summary* s);
// A matrix of exactly rows × cols (CheckpointError otherwise).
Eigen::MatrixXd GetMatrix(StateReader& r, Eigen::Index rows, Eigen::Index cols);

template <class T>
void PutDeque(StateWriter& w, const std::deque<T>& d) {
  w.U64(d.size());
  for (const T& x : d) Put(w, x);
}
template <class T>
void GetDeque(StateReader& r, std::deque<T>* d) {
  d->clear();
  for (std::size_t n = r.Count(kMaxStateCount); n > 0; --n) {
    T x;
    Get(r, &x);
    d->push_back(std::move(x));
  }
}

// Every option of a multi-tracker that its results depend on, and B0.
std::string OptionsBytes(const Eigen::Vector3d& B0_W, const MultiTrackerOptions& o);

}  // namespace magnav::tracker::internal
