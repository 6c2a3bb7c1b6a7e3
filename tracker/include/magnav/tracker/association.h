// The multi-tracker's data associator (Stone Soup's composition, STYLE §13):
// given every live track's predicted field at each sample of one epoch, it
// decides which samples each track gets and scores whether the track's field
// is there. No state: one call per epoch (MultiTracker, step 2 and 3 of
// multi_tracker.h).
//
// Frames and units as tracker.h: world NED, metres, seconds, T, T/m.
//
//  - Gate: a track takes the samples where its predicted signal SNR =
//    √(‖B̂‖²/σ_B² + ‖T̂‖²/σ_T²) ≥ gate_snr ("its sensors").
//  - Joint model, track by track: each such sample is handed over minus the
//    predicted fields of the other tracks (RemoveOtherFields: their model
//    error widens its σ), so two vessels seen by one sensor share it.
//  - Score: LLR = ½ Σ (‖m‖² − ‖m − ẑ‖²) over its sensors (m: the whitened
//    sample minus B0 and the other tracks; ẑ: the whitened prediction).
//    Detected: LLR ≥ detect_llr and not a poor fit; missed: LLR ≤
//    −detect_llr or a poor fit (residual χ² > max_chi2_per_dof per residual,
//    8 per sample, and > max_unexplained of the signal energy); otherwise
//    unobserved.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "magnav/core/gradiometer.h"
#include "magnav/tracker/multi_tracker.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

// One track's predicted field at one sample, and its SNR (see above).
struct FieldPrediction {
  Eigen::Vector3d B = Eigen::Vector3d::Zero();  // T
  Eigen::Matrix3d T = Eigen::Matrix3d::Zero();  // T/m
  double snr = 0.0;
};

// A track's predictions at every sample of the epoch (in the epoch's sample
// order); `valid` false: the track has no prediction this epoch (it takes no
// sample and removes nothing from the others').
struct TrackPrediction {
  bool valid = false;
  std::vector<FieldPrediction> at;
};

// The prediction of a dipole track (state, body moment) at a sample, with
// the sample's σ (or the options' defaults: SigmaB, SigmaT) for the SNR.
FieldPrediction PredictAtSample(const CtState<double>& state, const Eigen::Vector3d& m_B_Am2,
                                const GradiometerSample& sample, const TrackerOptions& options);

// What one track got from the epoch.
struct TrackAssociation {
  Epoch mine;             // its samples (others' fields removed), at the epoch's time
  double llr = 0.0;       // log-likelihood ratio of its field being there
  double sum_m2 = 0.0;    // whitened signal energy over its samples
  double sum_r2 = 0.0;    // whitened residual energy over its samples
  bool poor_fit = false;
  bool detected = false;
  bool missed = false;
};

// Per track (the order of `predictions`), its samples and score. Uses
// options.management's gate_snr, detect_llr, max_chi2_per_dof and
// max_unexplained, and options.track's default σ.
std::vector<TrackAssociation> AssociateEpoch(const Epoch& epoch, const std::vector<TrackPrediction>& predictions,
                                             const Eigen::Vector3d& B0_W, const MultiTrackerOptions& options);

}  // namespace magnav::tracker
