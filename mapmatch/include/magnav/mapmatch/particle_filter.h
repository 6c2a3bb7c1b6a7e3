// Sequential map matching (METHODS.md §6, after the adaptive-fission paper):
// a particle filter (PF) and the adaptive fission particle filter (AFPF),
// fed one INS/DR position and one measured map value at a time.
//
// Units: particle positions in degrees (lat, lon, used as a plane like the
// other matchers), map values and measurements in nT, covariances in deg².
//
// Model (both filters):
//   motion      x_k = x_(k−1) + (ins_k − ins_(k−1)) + n_k,  n_k ~ N(0, drift_sigma_deg² I)
//   likelihood  p(z | x) = exp(−(z − m(x))² / (2σ²)),  m = bilinear map value,
//               σ = measurement_sigma_nT (the paper's τ = σ²)
//   off the map p(z | x) = exp(−off_map_sigmas² / 2): a particle off the map
//               keeps a floor likelihood (that of an off_map_sigmas residual),
//               so a cloud that partly leaves the map is not wiped out, and
//               returns when its neighbours on the map do better. When every
//               particle is off the map the update is skipped (counted) and
//               the filter dead-reckons on the INS increments.
//   prior       uniform over the square of half-width prior_half_width_deg
//               around the first INS position, clipped to the map (the vehicle
//               being matched is taken to be on the map; an empty intersection
//               is an InputError).
//
// PF: weights w ← w·p(z|x), normalised; systematic resampling when the
// effective sample size 1/Σw² < resample_ess_fraction·N.
//
// PF, adaptive σ (adaptive_sigma, on by default; the AFPF ignores it): the
// sensor's noise is not known in advance (0.5–5 nT in this project's data),
// and one fixed σ must be as large as the worst of it, which throws away most
// of a quiet sensor's information. So the PF estimates it from its own
// innovations (Mehra's innovation-based adaptive estimation): over the
// predicted cloud, with m̄ = Σw m(x_i) and V = Σw (m(x_i) − m̄)², a consistent
// filter has E[(z − m̄)²] = σ² + V, so
//   σ_k² = mean over the last sigma_window updates of ((z − m̄)² − V),
// clamped to [min_measurement_sigma_nT², measurement_sigma_nT²];
// measurement_sigma_nT until the window is full; σ rises at once but falls by
// at most a factor (1 − 1/sigma_window) per update (the cloud's spread V lags
// σ: a sudden small σ collapses a cloud that has not tightened yet, measured
// on held-out paths). Only updates whose cloud is
// compact in map value (V ≤ measurement_sigma_nT²) enter the window, and a
// spread one empties it: while the cloud is still spread over several basins
// (acquisition, or after a re-initialisation) its mean residual says nothing
// about σ, and an early small σ collapses the cloud into whichever basin is
// ahead (measured on held-out paths, docs/ACCURACY.md). The AFPF's cloud is
// a rank selection, not a posterior sample, so the identity does not hold for
// it (measured: adaptive σ made its covariance and held-out errors worse).
//
// PF, tempered update (min_update_ess_fraction, 1 % by default): a reading
// that would leave fewer than that many effective particles (a steep stretch
// of map where the cloud's spread in map value is many σ wide, so only a
// handful of particles fit it) is applied as p(z|x)^β, the largest β ≤ 1
// whose ESS stays at the floor (β by bisection; the adaptive tempering of SMC
// samplers, Jasra et al. 2011, in one stage: the rest of the reading is
// dropped, not applied later). Without it such a reading collapses the cloud
// onto one particle, and the reported covariance is ~0 (measured: held-out
// path 45 at 3 nT, step 117, ESS 1.0). Counted (tempered_updates).
//
// Regularised PF (regularization_bandwidth, off by default): after resampling
// each particle moves by h·L·ε, L Lᵀ = the cloud's covariance, h = bandwidth ·
// N^(−1/6) (Musso, Oudjane & Le Gland 2001). With the cloud's global
// covariance as the kernel it blurs the basins during acquisition: on held-out
// paths it lost the track in most runs (docs/ACCURACY.md), so it is off.
//
// AFPF (the paper's algorithm 1): after the weight update each parent i
// spawns m_i = round(N w_i) + 2 offspring drawn from N(x_i, σ_i I) with the
// variance σ_i = λ μ a_i (deg²) and fission factor
//   a_i = 1 / (1 + exp((w_i − w_avg)/(w_max − w_avg)))   (a_i = 1/2 when all
//   weights are equal); light parents spread their offspring wider.
// Offspring are weighted like their parent (w_(k−1) of the parent times their
// own likelihood), parents and offspring are pooled, the N_k heaviest kept and
// renormalised. The estimate is the weighted mean. Two readings of the paper
// are fixed here: its eq. (10) prints λ μ (1 + exp(…)) = λ μ / a_i, against
// its text ("σ = λ μ a", fission factor as the variance scale) — the text is
// followed; and N(x, σ) there takes σ as a variance (μ = 1.6454e-4 deg² is a
// variance; read as a standard deviation the offspring would move ~2 cm).
// One change (fission_motion_penalty, on by default): an offspring's weight
// also pays its fission move as drift, exp(−|x̃ − x|²/(2 drift_sigma_deg²)).
// Without it the selection is by rank only, offspring move freely to fit each
// reading, and with 3 nT noise the filter chases the noise into a wrong basin
// (measured on the crustal reference paths: second-half mean error 4× the
// INS's on the 0.01° path; docs/ACCURACY.md). `fission_motion_penalty = false`
// is the paper's algorithm.
// Adaptive count (this library's, not the paper's, which keeps N fixed): the
// filter starts with max_particles (covering the wide prior) and after each
// step takes N_(k+1) = clamp(num_particles, max_particles,
// particles_per_cell · occupied map cells) (KLD-sampling's idea: the count
// follows the spread), dropping the lightest; it shrinks to N once the cloud
// has converged and stays large while it is spread or multimodal.
//
// Input at the door: a non-finite measurement skips the update (prediction
// still runs; counted); a non-finite INS position or an INS increment longer
// than max_step_deg is an INS jump — the increment is not applied (a reset or
// glitch is not vehicle motion), only the drift noise; counted.
//
// Divergence ("lost"): each update's normalised innovation
// NIS = Σ w_(k−1),i (z − m(x_i))²/σ² over the predicted cloud (particles on the
// map; σ: this update's, the adaptive one for the PF). The filter is lost while the mean NIS over the last divergence_window
// updates exceeds divergence_nis (a tracking filter's NIS is ≈ 1 plus the
// cloud's spread; a lost one sees the map's ±60 nT as residuals). It clears
// when the window's mean falls back. With reinitialize_when_lost the particles
// are then spread again over the prior square around the current INS position,
// and the filter stays lost until the new cloud has settled (settled_sigma_deg).
// A second rule, the innovation-bias test (bias_test_window, on for the AFPF),
// flags a run of biased innovations without re-spreading the cloud; the
// innovation CUSUM (on for the PF) a rise of the innovations above the noise
// the filter had before, likewise; a third,
// the track check (a coarse re-search, off by default), likewise. While lost
// the published covariance is at least the prior square's
// (lost_covariance_is_prior), not the cloud's.
//
// Randomness: one std::mt19937_64 seeded with `seed`; a run is reproducible
// bit for bit on one platform (the standard library's normal distribution
// differs between implementations).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "magnav/mapmatch/geo_grid.h"
#include "magnav/mapmatch/path.h"

namespace magnav::mapmatch {

enum class ParticleFilterKind { kPf, kAfpf };
const char* ParticleFilterKindName(ParticleFilterKind kind);  // "pf", "afpf"

struct ParticleFilterOptions {
  // Particles (the paper: 3000). PF: always this many; AFPF: the fewest it adapts down to.
  int num_particles = 3000;
  std::uint64_t seed = 1;
  // Likelihood σ (nT): sensor noise plus map error plus what the particles'
  // spacing leaves (a particle is rarely on the truth). Not the paper's
  // τ = 1e5 nT² (σ ≈ 316 nT, for its sensor and map): on the reference map
  // (anomaly std 60 nT) that makes every PF weight update ≈ 1. 5 nT: one
  // fixed value for the 0.5 nT and 3 nT reference paths (3 nT made the AFPF
  // lose 2 of 5 seeds at 3 nT noise, 10 nT widened the PF's posterior by 30 %).
  // The PF with adaptive_sigma: the largest σ, and the σ it starts with.
  double measurement_sigma_nT = 5.0;
  // PF: adaptive σ (see above): σ_k from the last sigma_window innovations,
  // clamped to [min_measurement_sigma_nT, measurement_sigma_nT]; with it
  // measurement_sigma_nT is the largest σ (and the σ until the window is
  // full). The floor 0.5 nT: the quietest sensor in this project's data (a
  // fluxgate's 0.5 nT; the map's own interpolation error is 0.06 nT rms on the
  // reference paths). The window 20: the σ² estimate's relative sd is then
  // ≈ √(2/20) ≈ 0.3 (a mean of 20 one-dof terms) and it follows a change of
  // sensor or map within 20 steps. Ignored by the AFPF.
  bool adaptive_sigma = true;
  double min_measurement_sigma_nT = 0.5;
  int sigma_window = 20;
  // AFPF: adaptive σ (see above; 0 = fixed at measurement_sigma_nT, the
  // filter before issue 25): σ = afpf_sigma_factor × the innovations' σ
  // estimate (the PF's, over sigma_window updates), clamped to
  // [measurement_sigma_nT, afpf_max_sigma_nT]; afpf_max_sigma_nT until the
  // window is full (and after a re-initialisation). The rank selection of the
  // fission collapses the cloud onto whichever basin fits the last few
  // readings best, so its likelihood must be wider than the noise: at 5 nT
  // noise and a fixed 5 nT σ it settled in a wrong basin (seed 1: by step
  // 10–14) on 10 of 10 reference seeds (mean second-half error 10.5× and 1.07×
  // the INS's, 0.01° / 0.1° paths); a fixed 15 nT held on 3 seeds, 10 nT
  // lost 1 of 3; at 0.5 nT noise σ = 5 nT stays the best (15 nT: 26–30 % of
  // the INS's error against 19 %). Factor 3: chosen on the reference paths
  // only (docs/ACCURACY.md, "5 nT"). The cap 20 nT (15 nT before 2026-11-26,
  // chosen on the reference paths): on the generated tuning paths 201–240
  // (5 nT) 15 left 2 of 20 0.01° paths in a wrong basin (mean second-half
  // error 43 % of the INS's, target ≤ 25 %), 20 none (14 %); held out
  // (501–540, looked at after the choice) 28 % → 16 % at 0.01°, 9 % → 2 % at
  // 0.1°; the reference 0.5 / 3 / 5 nT paths within about one seed-to-seed
  // sd (0.5 nT: +9 %; docs/ACCURACY.md, "AFPF at 5 nT with its defaults"). It waited on the
  // map-bias case, which the sampled bias failed at 20 (see estimate_bias).
  double afpf_sigma_factor = 3.0;
  double afpf_max_sigma_nT = 20.0;
  // Drift noise per step, per axis (deg). Default: the reference paths'
  // INS drift (a U(±0.0005°) step per axis, σ = 0.00029°), README §4b.
  double drift_sigma_deg = 0.0003;
  // The step length (m) drift_sigma_deg is for, at least. An INS drifts with
  // the distance it travels, not with how often it reports: while the INS
  // steps are shorter than this on average, the drift per step is
  // drift_sigma_deg · √(L̄ / drift_step_m), a random walk in distance, with L̄
  // the INS steps' running mean length (m; exponential, 20 steps; at least
  // 1 m, so a vessel at rest keeps some spread); longer steps keep
  // drift_sigma_deg. Default 50 m: the reference paths' steps are 45–154 m
  // (L̄ never below 80 m), so they are unchanged; a vessel reporting every
  // 2 m gets 0.14 × drift_sigma_deg. Without it the soak's 2 m path
  // (bench/soak.sh) put the AFPF 9 km off with σ 60 m (docs/ACCURACY.md,
  // "Dense readings"). 0 = drift_sigma_deg per step whatever its length.
  double drift_step_m = 50.0;
  // A reading is used only once the INS position is at least this far (m,
  // straight line) from where the last reading used was taken; the readings
  // in between are left out
  // (StepUpdate::kSpaced, counted in FilterCounters::spaced) while the
  // particles still move with every INS step. Readings a few metres apart
  // on a map of ~100 m cells repeat one another: updating at each of them
  // sharpens the weights on the reading's iso-line long before the track
  // has shown where along it, and the cloud collapses on a wrong place (the
  // soak's 2 m path: the AFPF 9 km off with σ 60 m even with the drift per
  // distance; decimated to ~25–50 m it tracks, 70–250 m against the INS's
  // 1.1 km). Default 25 m, a quarter of the crustal map's cell: the
  // reference and generated paths' steps (≥ 45 m) all update, unchanged.
  // 0 = every reading.
  double min_update_spacing_m = 25.0;
  // Half-width of the uniform prior square around the first INS position (deg).
  // Default 0.15°: covers the 0.1°-offset reference paths (≈ 11 km).
  double prior_half_width_deg = 0.15;
  // PF: resample (systematic) when ESS < this fraction of N.
  double resample_ess_fraction = 0.5;
  // PF: a reading that would leave fewer than this fraction of N effective
  // particles is applied tempered, p(z|x)^β with the largest β that keeps
  // the ESS at this floor (see above); 0 = off.
  double min_update_ess_fraction = 0.01;
  // PF: after resampling, jitter by a Gaussian kernel of width
  // regularization_bandwidth · N^(−1/6) times the cloud's covariance (the
  // regularised PF, see above); 0 = off (the default: it lost the track on
  // held-out paths), 1 = Musso's optimal width for a Gaussian density.
  double regularization_bandwidth = 0.0;
  // Off-map likelihood floor, in σ of residual.
  double off_map_sigmas = 3.0;
  // One reading's influence is bounded (a gate on the innovation): a reading
  // whose residual from the cloud's predicted map value, z − m̄, is beyond
  // outlier_sigmas · sqrt(σ² + V) (σ the likelihood σ, V the cloud's spread
  // of predicted map values) fits no particle: it is skipped (counted,
  // StepUpdate::kOutlier) and neither weights the particles nor enters the
  // adaptive σ; the divergence rule counts it as an NIS of outlier_sigmas²
  // (one spike cannot make the filter lost, a run of them does within 4
  // steps). Without it one +1000 nT spike gives the particles where the map
  // is highest all the weight. After max_consecutive_outliers skipped
  // readings in a row the next is applied whatever it says (a filter that is
  // lost must not gate away the readings that would show it). 0 = off.
  double outlier_sigmas = 5.0;
  int max_consecutive_outliers = 3;
  // An INS increment longer than this (deg) is a jump, not applied.
  double max_step_deg = 0.01;
  // INS glitch test (issue 25 item 3; docs/ACCURACY.md, "Lost-track detection, sixth round"): an
  // INS increment Δ (m, north/east) departs when it differs from the recent increments by more than
  // ins_glitch_ratio × max(√(L̄² + D̄²), a quarter of the map's cell) — L̄ the running mean step
  // length, D̄² the running mean square of |Δ − Δ̄|, Δ̄ the running mean increment (gain 0.1, ≈ 10
  // steps). A departing increment followed by a usual one is a one-step jump of the INS position, an
  // INS glitch; two departing in a row are a change of motion (a manoeuvre, a new speed), not a
  // glitch, and the statistics restart from it. Below max_step_deg a glitch is applied as motion (the
  // filter cannot tell it from a real move), so the filter follows the INS off the truth if the
  // vehicle did not move, and it says so: lost for ins_glitch_hold steps from the step after the
  // glitch (flag only; the cloud is not re-spread, the estimates are unchanged). What it sees is one
  // step many times the usual one, as a real INS position reset or a bad aiding fix gives (the kidnaps
  // of the lost-detection paths are such a step; a vehicle moved off its INS track slowly, by an
  // unsensed current, is not). 3.5 chosen on the tuning paths 301–420 of
  // tests/data/generated/pf_paths.csv (largest clean ratio 2.15, smallest kidnap step 4.1), the
  // reference paths (1.9) and 4000-step dense paths (2 m steps, drift per distance: 3.0). 0 = off.
  double ins_glitch_ratio = 3.5;
  int ins_glitch_hold = 20;
  // Divergence rule (see above).
  int divergence_window = 10;
  double divergence_nis = 9.0;
  // Track check (a second lost-track detector, issue 25): a coarse re-search
  // of the map. The divergence rule only hears readings that do not fit the
  // cloud, and a filter in a wrong basin, or moved off the truth by an unseen
  // INS jump, often fits them well enough locally. Every track_check_every
  // updates the last track_check_window readings are placed where the INS
  // increments put them relative to the estimate (the increments are what the
  // particles moved by; the estimated track's own jitter is not used) and the
  // whole track is shifted over offsets within ±prior_half_width_deg (grid
  // track_check_step_deg, the best 5 refined 5×). The filter is lost when the
  // best offset lies beyond 3 σ of its covariance and (SSE within 3 σ − best
  // SSE) / max(σ_n², best SSE / W) exceeds track_check_chi2; the verdict holds
  // until the next check; it flags, it does not re-spread the cloud. 0 = off,
  // the default: measured open-loop on the tuning paths 301–420 (window 20
  // and 10), at thresholds with ≤ 6 % false alarms it adds 0–3 losses of 51
  // (PF) and 0–1 of 59 (AFPF) to the other rules; at lower ones it flags
  // 6–87 % of clean runs (an INS-relative track drifts ≈ 0.001° over 20 steps, and
  // among the ≈ 15,000 offsets some fit such a track 2× better by chance;
  // docs/ACCURACY.md, "Lost-track detection, third round"). An option to
  // measure, not a detector to trust.
  int track_check_window = 0;
  int track_check_every = 5;
  double track_check_chi2 = 40.0;
  double track_check_step_deg = 0.0025;
  // The track check during acquisition only (issue 25 item 3, strict-detection round): with a
  // track_check_window, run the check only in the acquisition phase (from the first step until
  // acquisition_steps after the cloud's 1-σ first fell below settled_sigma_deg, as the acquisition
  // bias test) — where a cloud can have collapsed on a wrong basin — and not on a settled track,
  // where its chance fits raised the false alarms above. Measured offline from --diagnostics on
  // the tuning paths 301–420 (window 20, threshold 40): PF losses flagged within 20 steps 45 → 46
  // of 51 (path 396, a wrong-basin collapse), clean runs flagged 2 of 54 as without it (always on:
  // 11); AFPF 47 of 53 either way. Not the default (track_check_window stays 0): held out (541–660)
  // PF 40 → 42 of 54 and blind5 (1301–1360) 20 → 22 of 26, but blind5's clean PF runs flagged
  // 1 → 2 of 26 (8 %, above item 3's 5 %) and the harness's clean AFPF runs 1 → 2 of 36
  // (docs/ACCURACY.md, "PF/AFPF strict lost-track detection: the missed losses by kind").
  // false = the check at every step.
  bool track_check_acquisition_only = false;
  // Innovation-bias test (a third lost-track detector, issue 25): a filter on
  // the track sees zero-mean innovations z − m̄; one in a wrong basin, or
  // moved off the truth, sees the map's level there, a bias that the
  // likelihood σ (adaptive, rising at once) absorbs in the NIS but not in the
  // mean. Over the last bias_test_window updates (outlier-gated readings
  // included, the window emptied at a re-initialisation)
  //   B = (Σ r_j)² / Σ (σ_n,j² + V_j),  r_j = z_j − m̄_j,
  // V_j the predicted cloud's spread of map values, σ_n the noise the filter
  // sees (the PF's σ; the AFPF's σ / afpf_sigma_factor, at least 0.5 nT), is
  // χ²(1) for white innovations; lost when B exceeds the filter's threshold
  // (a tracking filter's innovations are correlated over a few steps, hence
  // thresholds far above χ²(1)'s 10.8 at p = 1e-3). The alarm sets `lost`
  // (and the run's status) but does not re-initialise: measured, a re-spread
  // AFPF re-acquires a smooth map worse than it was. Window 8 and thresholds
  // chosen on the tuning paths 301–420 of tests/data/generated/pf_paths.csv
  // only (docs/ACCURACY.md, "Lost-track detection"): the AFPF's 20 (at 12 it
  // flagged 19 % of clean tuning runs: its cloud is a rank selection whose
  // spread V understates its uncertainty); the PF's is 0 = off by default:
  // at 12 (in a first version that also re-initialised on this alarm) it
  // raised no unjustified alarm on the tuning runs but 6 of 48 clean held-out
  // runs (13 %, target ≤ 5 %), so it stays an option to measure.
  int bias_test_window = 8;
  double bias_test_chi2 = 0.0;
  double afpf_bias_test_chi2 = 20.0;
  // The bias test during acquisition (issue 25 item 3, sixth round): from the first step until
  // acquisition_steps steps after the cloud's 1-σ spread √(cloud_cov_lat_lat + cloud_cov_lon_lon) has
  // first fallen below settled_sigma_deg, the bias test also runs with this threshold (the lower of
  // the two when both are on). An acquisition loss (the cloud collapsing on a wrong basin while
  // still wide) has no "before" for the CUSUM to compare with; its innovations, once the cloud
  // narrows there, are biased. The PF's 12 (and 20 steps) chosen on the tuning paths 301–420 only
  // (one run per path, the statistic computed offline from --diagnostics): PF acquisition losses
  // flagged within 20 steps 4 → 10 of 14, no clean run flagged that was not before (2 of 54);
  // 10 flagged 2 more clean runs, 15 only 7 of 14 losses. The AFPF's 0 = off: it flagged none of
  // its 5 acquisition losses (its cloud is already narrow, 0.001°, and only 0.003° off) at 12.
  // Known: on scripts/calibration's two PF scenarios it raised the clean runs flagged from 6 % to
  // 11 % (0.01°/3 nT) and 25 % (0.1°/5 nT); with acquisition_collapse_ratio (below) 6 % and 19 %,
  // still above item 3's 5 % at 0.1°/5 nT (docs/ACCURACY.md, "Lost-track detection, seventh round").
  double acquisition_bias_test_chi2 = 12.0;
  double afpf_acquisition_bias_test_chi2 = 0.0;
  int acquisition_steps = 20;
  // The acquisition test's window after a collapse (issue 25 items 3, 4, seventh round): a cloud
  // that narrows from a wide prior onto its basin sees large, same-signed innovations while it
  // migrates (the predictive mean of a wide, moving cloud is not the reading's), and a window that
  // still holds them raised the harness's false alarms (docs/ACCURACY.md, "Lost-track detection,
  // seventh round"). The acquisition test's window therefore holds only the innovations predicted
  // by a cloud comparable to the current one: at each step, those recorded while the cloud's 1-σ
  // spread √(cloud_cov_lat_lat + cloud_cov_lon_lon) (after that step's update) exceeded
  // acquisition_collapse_ratio × the current spread are dropped, and the test needs at least
  // acquisition_min_updates of them (≤ bias_test_window). A wrong basin's bias persists after the
  // collapse and refills the window; a migration's does not. Flag only (estimates unchanged bit for
  // bit). 0 = off (the sixth round's window: the last bias_test_window updates). 2 and 6 chosen on
  // the tuning paths 301–420 and the harness's two PF scenarios (offline from --diagnostics).
  double acquisition_collapse_ratio = 2.0;
  int acquisition_min_updates = 6;
  // Innovation CUSUM (a fifth lost-track detector, issue 25 item 3, fifth round): a kidnap (the
  // filter moved off the truth by an unseen INS error) shows at once as innovations far larger
  // than the filter's recent ones — the first readings after a 0.008° kidnap on the tuning paths
  // had |z − m̄| of 6–36 nT against 0.4–3 nT before — but the filters' own σ rises at once to
  // absorb them (the PF's to its cap within 1–3 updates), so the NIS-based divergence rule, which
  // divides by the new σ, stays quiet. This test divides by the noise the filter had *before*: over
  // the updates that ended innovation_cusum_delay updates ago, the last innovation_cusum_window of
  // them, s² = mean(r_j² − V_j) (at least 0.25 nT²: the quietest sensor's 0.5 nT), and each
  // update's u = min(r² / (s² + V), innovation_cusum_cap) feeds a one-sided Page CUSUM
  //   g ← max(0, g + u − innovation_cusum_drift),
  // lost while g > the filter's threshold (a Page test for a rise of the innovations' variance:
  // its log-likelihood ratio for a variance ratio ρ is linear in u). The cap bounds one reading's
  // push (a spike adds at most cap − drift = 6 < the threshold); the delay keeps the first
  // readings of a kidnap out of their own reference. Flags, does not re-spread the cloud (like
  // the bias test); the window and g are emptied at a re-initialisation. Window 40, delay 5, drift 3,
  // cap 9 and the PF's threshold 25 chosen on the tuning paths 301–420 of
  // tests/data/generated/pf_paths.csv only (one run per path, the statistic computed from
  // --diagnostics offline; docs/ACCURACY.md, "Lost-track detection, fifth round"): PF 11 → 19 of
  // 51 losses flagged within 20 steps, 2 of 54 clean runs flagged (0 before); held out (541–660)
  // 11 → 20 of 54, 1 of 48 clean flagged (as before); blind (901–980) 4 → 9 of 42, 0 of 33. Not
  // item 3's 90 %: acquisition losses and kidnaps whose readings differ by less than the noise
  // are not in the innovations. The AFPF's threshold is 0 = off: on the tuning runs it added no
  // loss flagged within 20 steps to its bias test (32 of 53 either way) and one false alarm.
  int innovation_cusum_window = 40;
  int innovation_cusum_delay = 5;
  double innovation_cusum_drift = 3.0;
  double innovation_cusum_cap = 9.0;
  double innovation_cusum_threshold = 25.0;
  double afpf_innovation_cusum_threshold = 0.0;
  // After a re-initialisation the filter stays lost (StepDiagnostics::lost,
  // reacquiring; the run's status) until its cloud has settled again: 1-σ
  // spread √(cov_lat_lat + cov_lon_lon) below settled_sigma_deg (≈ 300 m),
  // for at most 2 × divergence_window steps (a smooth map may never
  // tighten a cloud that far). A re-acquiring cloud's estimate lies between
  // basins and must not be trusted; before, the flag cleared at once and a
  // re-acquisition that locked onto a wrong basin was never flagged. 0 = off.
  double settled_sigma_deg = 0.003;
  // The converging status (issue 25 items 3, 4; StepDiagnostics::converging, StatusOf): a filter
  // says it has not settled yet, so that a wide cloud's mean is never published as a trusted fix
  // (OK). A step is converging — unless lost — from the first step, and again after a
  // re-initialisation or whenever the cloud widens, until the cloud has been settled for
  // settle_updates updates in a row: its 1-σ spread √(cloud_cov_lat_lat + cloud_cov_lon_lon) below
  // settled_sigma_deg (the re-acquisition's settle criterion above) after each of them; with
  // subclouds > 1, every sub-cloud settled and the pooled cloud (which holds their disagreement)
  // too. settle_updates = acquisition_min_updates (6): the acquisition test (below) then has had
  // its minimum window of innovations from the settled cloud to judge before the fix is called OK,
  // so a wrong-basin collapse goes from converging to lost, not through OK. Not chosen on any run
  // (both constants predate the status); its effect measured in docs/ACCURACY.md ("A converging
  // status"). Status only: the estimates and the lost flags are unchanged (the published covariance
  // of a converging step: converging_covariance_mixture).
  // 0 = off (never converging).
  int settle_updates = 6;
  // On by default: on the crustal 0.01°/3 nT path 1 of 20 AFPF seeds locks
  // onto a wrong basin early; the rule flags it and a fresh prior finds the
  // track (docs/ACCURACY.md).
  bool reinitialize_when_lost = true;
  // While lost, the published covariance (StepDiagnostics::cov_*, the CLI's
  // output and MapFix's σ) is at least the prior square's, h²/3 per axis
  // (h = prior_half_width_deg), not the cloud's: a cloud collapsed on a wrong
  // place says nothing of the error (issue 25 item 4; docs/ACCURACY.md).
  bool lost_covariance_is_prior = true;
  // While converging (StepDiagnostics::converging), the published covariance covers every cloud the
  // filter has held since it started converging (issue 25 item 4), not only the current one: the
  // covariance, about the current mean, of the equal mixture of those steps' cloud Gaussians, each
  // taken as an offset from its own step's INS position (so the INS motion does not count, only how
  // the filter's belief about the INS error moved): (1/n) Σ_i [C_i + (o_i − o)(o_i − o)ᵀ] over the
  // cloud of the step before the episode (the last ok or lost step's; none at the run's start) and
  // the n − 1 converging steps so far, published when its trace exceeds the cloud's. A filter that has not
  // settled has not shown that its latest cloud, rather than those it held before, holds the truth:
  // a wide cloud that collapsed onto one basin keeps the spread of the clouds before the collapse
  // until it has settled, a cloud migrating between basins the spread of its path. The episode
  // starts again at each step that is not converging (ok, lost) and at a re-initialisation. No
  // constant: each step's covariance from the filter's own clouds (not a global factor).
  // false = the cloud's own (as before). The estimates, the lost flags and the statuses do not
  // depend on it (cloud_cov_* keep the cloud's own). Measured in docs/ACCURACY.md ("The converging
  // regime's covariance"). The PF's (on); the AFPF's is afpf_converging_covariance_mixture (off: its
  // converging steps were calibrated with the cloud's own — harness ANEES 2.3 and 1.59 — and the
  // mixture made them 0.52 and 0.27, below 0.5 × dof).
  bool converging_covariance_mixture = true;
  bool afpf_converging_covariance_mixture = false;
  // The offset-slide test (issue 25 item 3, "no converged that is not"; docs/ACCURACY.md, "Dense
  // readings III"): a status rule of RunStatus (run_status.h: `magnav match`'s summary and
  // magnav-matcher's fixes), flag only — the estimates and the per-step lost flags are unchanged. The
  // particles move with the INS increments plus the drift noise, so the estimate's offset from the
  // INS, Δ_k = x̂_k − ins_k, changes between two steps by the drift the filter's own model allows
  // plus the change of its cloud. Over the last offset_slide_updates updates (from the step of the
  // first of them, s, to the run's last step, e; restarted after an INS jump or a re-initialisation)
  //   χ² = (Δ_e − Δ_s)ᵀ (C_s + C_e + Q I)⁻¹ (Δ_e − Δ_s),  2 dof, in deg,
  // C the cloud's covariance (cloud_cov_*) at those steps, Q = Σ DriftSigmaPerStep² over the steps
  // after s (StepDiagnostics::drift_sigma_deg); the run is "not converged" when χ² >
  // offset_slide_chi2 (fewer updates since the start or the last restart: not tested). A filter
  // settled in a wrong place keeps sliding against the INS (the readings its place does not
  // explain pull its cloud along), kilometres per few kilometres of
  // track, while its NIS rules stay quiet (its σ and spread absorb the mismatch). Measured offline
  // from --diagnostics on the dense tuning paths 9001–9006 (3 filter seeds) and fresh 9101–9110
  // (seed 1; both looked at), runs judged at their last step: on the track χ² ≤ 2.7 (PF) and ≤ 9.8
  // (AFPF, fresh 9102: still sliding onto the track in its last 2 km), > 1 km off 17–44 (PF) and
  // 22–54 (AFPF), except PF fresh 9103 (0.2: its cloud 4 km wide). 80 updates (≈ 2 km at the 25 m
  // update spacing; 40: less contrast, 160: flags runs still converging) and 13.8 (χ²(2) at
  // p = 0.001, as subcloud_chi2; 9.21, p = 0.01, would flag AFPF fresh 9102). On dense readings
  // only (some reading spaced out by min_update_spacing_m), like the AFPF's cap rule: on the
  // held-out paths (100 m steps; scripts/heldout_pf, 10 paths, seed 1, 0.01°) it flagged 2 of 20
  // AFPF runs on the track (its rank-selected cloud's covariance is narrower than its moves), so the
  // reference and held-out paths keep their status bit for bit. 0 = off.
  int offset_slide_updates = 80;
  double offset_slide_chi2 = 13.8;
  // Independent sub-clouds (a fourth lost-track detector, and the covariance
  // of an ambiguous cloud; issue 25 items 3, 4; particle_filter_subclouds.cc).
  // subclouds = K > 1 runs K filters of the same kind side by side, each with
  // num_particles (and max_particles) of its own — the cost is K times one
  // filter's — its own seed, resampling, σ and detectors, on the same map and
  // readings. (Splitting num_particles K ways was measured first: 1000-particle
  // sub-clouds collapse on wrong basins far more often than one of 3000.)
  // Published: the pooled cloud (every sub-cloud weighted 1/K), i.e. the mean
  // of the sub-cloud means and the mixture covariance (the mean
  // within-sub-cloud covariance plus the spread of the means). A wrong-basin
  // collapse is a random event per sub-cloud, so sub-clouds that sample the
  // same posterior agree and one that collapsed elsewhere does not: the
  // filter is lost while some pair's means differ beyond their combined
  // covariance,
  //   D = max over pairs (m_i − m_j)ᵀ (C_i + C_j)⁻¹ (m_i − m_j) > subcloud_chi2
  // (χ²(2): 13.8 is p = 0.001 for two independent Gaussian estimates), for
  // subcloud_hold steps in a row; or when any sub-cloud's own rules say so.
  // The disagreement flags and does not re-spread (like the bias test).
  // Re-seeding (subcloud_reseed_nats > 0; 0 = off): while they disagree, a sub-cloud
  // whose summed log evidence over the last subcloud_window updates,
  // Σ log Σ_i w_i N(z; m(x_i), σ²), is below the best one's by more than
  // subcloud_reseed_nats is replaced by a copy of the best (with a fresh
  // seed): the data prefer the best one's basin by that likelihood ratio.
  // Hold 8 and re-seeding at 3 nats: chosen on the tuning paths 301–340 of
  // tests/data/generated/pf_paths.csv (PF, K = 3): with hold 3 and 10 nats
  // the sub-clouds' transient disagreements during acquisition (4–29 steps,
  // until the evidence separates them) flagged 15 of 60 clean runs (25 %);
  // 5 nats / hold 3: 8 of 49, 5 / 6: 6 of 49, 3 / 8: 1 of 49; with 3 / 8 the
  // out-scored sub-cloud is usually re-seeded before the flag, and the flag
  // is left to disagreements the data do not settle.
  // subclouds 1 = off (one filter, the default: K sub-clouds cost ≈ K times
  // one filter, and on the tuning runs they remove the acquisition losses
  // rather than flag them, leaving the kidnaps to the other rules;
  // docs/ACCURACY.md, "Lost-track detection, fourth round").
  int subclouds = 1;
  double subcloud_chi2 = 13.8;
  int subcloud_hold = 8;
  int subcloud_window = 10;
  double subcloud_reseed_nats = 3.0;
  // Ensemble disagreement during acquisition (a lost-track flag for the acquisition kind of loss;
  // issue 25 item 3; particle_filter_ensemble.cc). acquisition_ensemble = K > 1 runs K − 1 shadow
  // filters of the same kind beside the filter, each with its own particles and seed (the
  // sub-clouds' seeds), on the same readings, only while the filter acquires: from its first step
  // (and again from a re-initialisation) until acquisition_steps after its first ok step (not lost,
  // not converging). The filter's estimate, cloud and own flags are published unchanged (the
  // shadows are not pooled, unlike subclouds); the step is flagged lost while the filter's mean and
  // some shadow's differ beyond their summed cloud covariances,
  //   E = max over shadows (m − m_s)ᵀ (C + C_s)⁻¹ (m − m_s) > acquisition_ensemble_chi2
  // and the readings do not favour the filter over that shadow: its summed log evidence over the
  // last acquisition_ensemble_window readings, Σ log Σ w N(z; m(x), σ²), is not below the filter's by
  // more than acquisition_ensemble_nats (a shadow settled in a worse basin is the shadow's loss, not
  // the filter's) — for acquisition_ensemble_hold steps in a row (a wrong-basin settle is a random event per
  // cloud: an independently seeded cloud that settles elsewhere says the mode is ambiguous).
  // Flag only: no re-spread. Cost: K − 1 more filters during acquisition only.
  // K = 3, E > 50, hold 3, window 10, 0 nats: chosen on the tuning paths 301–420 and the calibration
  // harness (PF losses flagged within 20 steps 45 → 48 of 51, clean runs flagged 2 of 54 either way;
  // harness 3 of 6 either way, clean 4 → 5 of 34; the AFPF gains none, tuning clean 1 → 2 of 57;
  // without the evidence condition, E > 13.8: 49 of 51 but 13 of 54 clean runs flagged — clean
  // acquisitions' shadows settle in wrong basins as often as lost filters' shadows find the truth).
  // Held out (541–660): PF 40 → 45 of 54, clean 1 → 3 of 48 (6 %); AFPF 46 → 47 of 52, clean 1 of 56.
  // 1 = off (the default: clean alarms above item 3's 5 % held out and on the harness;
  // docs/ACCURACY.md, "Ensemble disagreement during acquisition").
  int acquisition_ensemble = 1;
  double acquisition_ensemble_chi2 = 50.0;
  int acquisition_ensemble_hold = 3;
  int acquisition_ensemble_window = 10;
  double acquisition_ensemble_nats = 0.0;
  // Whether the shadows' disagreement flags a step lost (the rule above). false: the shadows run
  // (for acquisition_ensemble_covariance) and the diagnostics' ensemble_* are written, but no step is
  // flagged by them: the lost flags, statuses and counters are the filter's alone.
  bool acquisition_ensemble_flag = true;
  // The published covariance while the shadows run (issue 25 item 4; docs/ACCURACY.md, "The PF's
  // converging covariance from the shadows' spread"). A wrong-basin settle is a random event per cloud,
  // so the shadows' spread is evidence of the multimodality the filter's own cloud hides. With
  // acquisition_ensemble > 1 and this not kOff, a step the shadows ran at that is converging or ok
  // (not lost) publishes, about the filter's mean m (the estimate stays the filter's), the covariance
  // of the mixture of the K clouds' published distributions (mean m_i, covariance C_i, deg²; the
  // filter's i = 0; a lost shadow's C_i is its cloud's, not the prior square's):
  //   Σ_i w_i [C_i + (m_i − m)(m_i − m)ᵀ],  when its trace exceeds the published one.
  // Weights: kEqual 1/K; kEvidence ∝ exp(the cloud's summed log evidence over the last
  // acquisition_ensemble_window readings) (the flag's evidence statistic). Lost steps keep their
  // covariance; the estimates, cloud_cov_*, lost flags and statuses do not depend on it. kOff: as before.
  enum class EnsembleCovariance { kOff, kEqual, kEvidence };
  EnsembleCovariance acquisition_ensemble_covariance = EnsembleCovariance::kOff;
  // With acquisition_ensemble_covariance: the offsets' term Σ w_i (m_i − m)(m_i − m)ᵀ replaced by its
  // trace split evenly over the two axes, Σ w_i |m_i − m|² / 2 · I (K ≤ 3 offsets from the filter's mean
  // span at most two directions, often one: the truth of a wrong-basin settle is rarely along it).
  // false: the mixture's own (anisotropic) covariance.
  bool acquisition_ensemble_isotropic = false;
  // AFPF: λ (the paper: 0.001) and μ, the parents' sampling variance per axis
  // (the paper: 1.6454e-4 deg²).
  double fission_lambda = 0.001;
  double fission_mu_deg2 = 1.6454e-4;
  // AFPF: an offspring's weight also pays its fission move as drift,
  // exp(−|x̃ − x|²/(2 drift_sigma_deg²)) (not in the paper; see above).
  bool fission_motion_penalty = true;
  // Map bias (optional third state, nT): z = m(x) + b + noise. Given a
  // particle's track the bias is linear-Gaussian, so it is marginalised, not
  // sampled (a Rao-Blackwellised filter: Doucet et al. 2000; Schön, Gustafsson
  // & Nordlund 2005): each particle carries the bias's posterior N(b_i, P_i)
  // given its own track, a scalar Kalman filter (prior N(0,
  // bias_prior_sigma²), random walk bias_drift_sigma per step, update by the
  // residual r = z − m(x_i) − b_i with variance σ² + P_i, the particle's
  // likelihood N(r; 0, σ² + P_i)); AFPF offspring start from their parent's
  // prior (b, P) and are updated by their own residual. The predicted spread V
  // of the innovations (adaptive σ, outlier gate, bias test) includes the mean
  // P. Why not sampled (the filter before 2026-11-26): a sampled bias moves by
  // bias_drift_sigma per step, so a cloud that collapsed with a wrong bias
  // cannot correct it; the AFPF then settled on a wrong position-bias pair
  // (synthetic map, +25 nT: 1 of 10 seeds with afpf_max_sigma_nT 15, 2 of 10
  // with 20, each 3× the INS's error with a bias of 9–11 nT; marginalised 0 of
  // 10 at both; docs/ACCURACY.md). Off by default (no extra random draws: runs
  // without it are unchanged).
  bool estimate_bias = false;
  double bias_prior_sigma_nT = 30.0;
  double bias_drift_sigma_nT = 0.2;
  // AFPF adaptive count: start (and cap), and particles per occupied map cell.
  int max_particles = 30000;
  double particles_per_cell = 30.0;

  bool IsValid(std::string* error) const;
};

// The drift per step and axis (deg) for INS steps of running mean length mean_step_m (m; < 0: not
// known yet, drift_sigma_deg): drift_sigma_deg · √(clamp(mean_step_m, 1, drift_step_m) / drift_step_m)
// (ParticleFilterOptions::drift_step_m; 0 = drift_sigma_deg).
double DriftSigmaPerStep(const ParticleFilterOptions& options, double mean_step_m);

// One particle (deg) and its normalised weight.
struct Particle {
  double lat_deg = 0.0, lon_deg = 0.0;
  double bias_nT = 0.0;       // map bias estimate given this particle's track (0 unless estimate_bias)
  double bias_var_nT2 = 0.0;  // its variance, nT² (0 unless estimate_bias)
  double weight = 0.0;
};

// What happened to a step's measurement.
// kOutlier: the reading was beyond outlier_sigmas of the whole cloud's
// prediction and skipped (ParticleFilterOptions::outlier_sigmas).
// kSpaced: the reading left out, the INS has moved less than min_update_spacing_m since the last one used.
enum class StepUpdate { kUpdated, kBadMeasurement, kAllOffMap, kOutlier, kSpaced };

// The status of a run as of a step (RunStatus, run_status.h, says which rule each names).
enum class RunVerdict { kConverged, kLost, kOffMap, kSigmaCapped, kSlid, kUnsettled, kImplausible, kNonFinite, kConverging };
// "converged", "lost", "off_map", "sigma_capped", "slid", "unsettled", "implausible", "non_finite",
// "converging".
const char* RunVerdictName(RunVerdict v);

// Diagnostics after one step.
struct StepDiagnostics {
  double lat_deg = 0.0, lon_deg = 0.0;                    // weighted mean
  // The published covariance, deg²: the cloud's (weighted), or while lost at least the prior
  // square's (lost_covariance_is_prior), while converging the mixture of the clouds since it
  // started converging (converging_covariance_mixture); the cloud's own in cloud_cov_*.
  double cov_lat_lat = 0.0, cov_lat_lon = 0.0, cov_lon_lon = 0.0;
  double cloud_cov_lat_lat = 0.0, cloud_cov_lat_lon = 0.0, cloud_cov_lon_lon = 0.0;
  double bias_nT = 0.0, bias_sigma_nT = 0.0;                       // weighted mean and sd of the map bias
  double ess = 0.0;              // 1/Σw² after the update (before resampling)
  int particles = 0;             // after the step
  int unique_particles = 0;      // distinct particles after the step (resampling copies)
  int occupied_cells = 0;        // distinct map cells holding a particle (spread)
  double nis = 0.0;              // this update's normalised innovation (0 if no update)
  double sigma_nT = 0.0;         // the likelihood σ of this step (measurement_sigma_nT unless adaptive_sigma)
  double likelihood_exponent = 1.0;  // β of a tempered PF update (1: the reading applied in full)
  double drift_sigma_deg = 0.0;      // the drift noise per axis of this step's prediction (deg; DriftSigmaPerStep)
  double track_check_chi2 = 0.0;     // the track check's statistic at this step (0: not run)
  // The predictive moments of this reading over the predicted cloud's particles on the map
  // (weights w_(k−1)): innovation z − m̄ and the spread √V of the predicted map values, nT
  // (with estimate_bias: of m(x) + b, and V includes the particles' mean bias variance P)
  // (NaN when less than half the weight is on the map or the reading is not finite).
  double innovation_nT = std::numeric_limits<double>::quiet_NaN();
  double predicted_spread_nT = std::numeric_limits<double>::quiet_NaN();
  double innovation_bias_chi2 = 0.0;  // the innovation-bias test's statistic B (0: window not full)
  double innovation_cusum = 0.0;      // the innovation CUSUM's statistic g (0: window not full or off)
  bool reacquiring = false;           // lost only because a re-initialised cloud has not settled yet
  bool track_check_failed = false;   // the track check made this step lost
  // subclouds > 1: the largest pairwise disagreement D of the sub-cloud means (0: one cloud),
  // and whether it is above subcloud_chi2 at this step (lost once held subcloud_hold steps).
  double subcloud_chi2 = 0.0;
  bool subclouds_disagree = false;
  // acquisition_ensemble > 1: the largest disagreement E of the filter's mean with a shadow's (0 while
  // the shadows do not run), that shadow's distance from the filter (deg), and whether the step
  // disagrees (E above acquisition_ensemble_chi2, that shadow not worse by acquisition_ensemble_nats;
  // lost once held acquisition_ensemble_hold steps).
  double ensemble_chi2 = 0.0;
  double ensemble_separation_deg = 0.0;
  double ensemble_evidence_nats = 0.0;  // that shadow's windowed log evidence less the filter's
  bool ensemble_disagree = false;
  bool resampled = false;
  bool ins_jump = false;
  // The INS increment's departure from the recent ones over max(√(L̄² + D̄²), a quarter cell)
  // (ins_glitch_ratio; 0 at the first steps, or when the test is off), and whether this step is lost
  // because of an INS glitch (within ins_glitch_hold steps of one).
  double ins_step_ratio = 0.0;
  bool ins_glitch = false;
  StepUpdate update = StepUpdate::kUpdated;
  bool lost = false;
  // Not lost and not settled yet (settle_updates): the cloud still wide, or settled for fewer than
  // settle_updates updates since the start, a re-initialisation or its last widening.
  bool converging = false;
  // The map knows less than the INS prior along its least observed direction
  // at this step (StepObservability, observability.h; set by magnav-matcher,
  // which then floors cov_* there; the filters and Match leave it false).
  bool partly_observable = false;
  // The run's status as of this step, had it ended here (RunStatus, run_status.h: set by
  // MatchParticleFilter and magnav-matcher, the same rules; the filters leave kConverged).
  RunVerdict run_status = RunVerdict::kConverged;
};

// A step's status as published (`magnav match`'s `status` column, magnav-matcher's MapFix.status):
// lost (StepDiagnostics::lost) outranks off the map (every particle off the map at this step), which
// outranks converging (StepDiagnostics::converging); else ok.
enum class StepStatus { kOk, kConverging, kLost, kOffMap };
StepStatus StatusOf(const StepDiagnostics& d);
const char* StepStatusName(StepStatus s);  // "ok", "converging", "lost", "off_map"

struct FilterCounters {
  int steps = 0, updates = 0, bad_measurements = 0, all_off_map = 0, ins_jumps = 0, resamples = 0,
      lost_steps = 0, reinitialisations = 0, tempered_updates = 0, outliers = 0, track_check_failures = 0,
      bias_test_failures = 0, innovation_cusum_alarms = 0;
  int ins_glitches = 0;      // INS increments beyond ins_glitch_ratio (each starts ins_glitch_hold lost steps)
  int subcloud_reseeds = 0;  // subclouds > 1: sub-clouds replaced by a copy of the best (subcloud_reseed_nats)
  int spaced = 0;            // readings left out by min_update_spacing_m
  int converging_steps = 0;  // steps with StepDiagnostics::converging
  int ensemble_lost_steps = 0;  // acquisition_ensemble > 1: steps lost by the ensemble disagreement alone
};

// The common interface of the PF and the AFPF.
class SequentialMatcher {
 public:
  virtual ~SequentialMatcher() = default;
  // One INS position (deg) and the value measured there (nT; NaN = none).
  // The first call places the prior around this INS position.
  virtual const StepDiagnostics& Step(double ins_lat_deg, double ins_lon_deg, double measured_nT) = 0;
  virtual const std::vector<Particle>& particles() const = 0;
  virtual const FilterCounters& counters() const = 0;
  virtual const StepDiagnostics& last() const = 0;
  virtual ParticleFilterKind kind() const = 0;
  bool lost() const { return last().lost; }
};

// A PF or an AFPF on `layer` of `grid` (kept by reference: must outlive the
// filter). Throws InputError on invalid options or a missing layer.
std::unique_ptr<SequentialMatcher> MakeParticleFilter(ParticleFilterKind kind, const GeoGrid& grid,
                                                      std::size_t layer, const ParticleFilterOptions& options);

// Runs a filter over a whole path (what `magnav match --method pf|afpf` does):
// the matched position of point k is the estimate after step k. score = mean
// ESS over the path; converged = not lost at the last step (reason names the
// first lost step), and for the AFPF on dense readings (some reading spaced
// out by min_update_spacing_m) its likelihood σ not at afpf_max_sigma_nT in
// half or more of its last 40 updates (the innovations beyond the largest
// noise it allows; docs/ACCURACY.md, "Dense readings II"), and for both filters on
// dense readings the estimate not slid against the INS beyond the drift model and
// the cloud (offset_slide_updates, offset_slide_chi2; "Dense readings III"), no estimate
// further from its INS position than max_correction_deg (0 = 2 × prior_half_width_deg), and not
// converging at the last step (settle_updates: a filter that has not settled never says
// "converged"): the rules of RunStatus (run_status.h), which magnav-matcher applies at every fix;
// points_used =
// updates; off map = all-off-map steps.
// `steps` (optional) receives every step's diagnostics, run_status the run's status as of it.
MatchResult MatchParticleFilter(ParticleFilterKind kind, const GeoGrid& grid, std::size_t layer,
                                const MatchPath& path, const ParticleFilterOptions& options,
                                std::vector<StepDiagnostics>* steps = nullptr, double max_correction_deg = 0.0);

}  // namespace magnav::mapmatch
