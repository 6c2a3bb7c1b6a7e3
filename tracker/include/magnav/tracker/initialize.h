// Track initialisation from single-sample fixes.
//
// Frames and units: world NED, metres, seconds, tesla, T/m, A·m², radians.
//
// Each strong sample (‖T‖_F ≥ min_tensor_snr · σ_T) gives a dipole position
// p_D = p_S − r by TED+EGT (see SingleSampleOffset). A robust straight-line
// fit p(t) = p̄ + v (t − t̄) over the fixes within ±span_s/2 of the strongest
// signal gives position, speed and heading
// (turn rate 0); the body moment is the component-wise median of
// Rz(h)ᵀ m_W with m_W = FitDipoleMoment at each fix.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "magnav/core/motion.h"
#include "magnav/tracker/options.h"
#include "magnav/tracker/tracker.h"

namespace magnav::tracker {

// Offset r_DtoS (m, dipole → sensor) from one sample by the inverter's scaled
// TED+EGT (magnav::inversion::SolveTedEgt with its default row weight).
// dB_W = B − B0 (T), T in T/m. nullopt if T = 0 or the result is not finite.
std::optional<Eigen::Vector3d> SingleSampleOffset(const Eigen::Vector3d& dB_W, const Eigen::Matrix3d& T);

struct DipoleFix {
  double t_s = 0.0;
  std::uint32_t sensor_id = 0;
  Eigen::Vector3d p_DinW = Eigen::Vector3d::Zero();  // m
  double tensor_snr = 0.0;                           // ‖T‖_F / σ_T
};

struct InitialTrack {
  double t_ref_s = 0.0;    // time of `state`
  double t_first_s = 0.0;  // time span of the inlier fixes
  double t_last_s = 0.0;
  CtState<double> state{};  // straight-line state at t_ref_s (ω = 0)
  Eigen::Vector3d m_B_Am2 = Eigen::Vector3d::Zero();
  std::vector<DipoleFix> fixes;  // inliers used
};

// Fixes of every strong sample of the epochs.
std::vector<DipoleFix> StrongFixes(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                   const TrackerOptions& options);

// Initial track, or nullopt if there are too few strong fixes.
std::optional<InitialTrack> InitializeTrack(const std::vector<Epoch>& epochs, const Eigen::Vector3d& B0_W,
                                            const TrackerOptions& options);

// Effective sensor sigmas of a sample (the sample's, else the options').
double SigmaB(const GradiometerSample& s, const TrackerOptions& options);
double SigmaT(const GradiometerSample& s, const TrackerOptions& options);

}  // namespace magnav::tracker
