// The tracker's flags, shared by `magnav track` and `magnav-tracker`: the
// sliding window, the robust losses, the process noise, track initiation and
// the multi-vessel track management (tracker/multi_tracker.h). Each flag's
// default is the option's documented default; a config file's keys are the
// flag names. Header-only: the program that includes it links
// magnav::tracker.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "magnav/cli/options.h"
#include "magnav/core/error.h"
#include "magnav/tracker/multi_tracker.h"

namespace magnav::cli {

// What the flags fill; ApplyTrackerFlags turns it into options.
struct TrackerFlags {
  tracker::MultiTrackerOptions options;
  std::string loss = tracker::LossTypeName(tracker::TrackerOptions{}.measurement_loss);
  std::string turn_loss = tracker::LossTypeName(tracker::ProcessNoise{}.turn_rate_loss);
  std::string init_from = tracker::InitSourceName(tracker::InitOptions{}.source);
  // auto: the library default (on) unless a background model is chosen, with
  // which it is exclusive.
  std::string far_source = "auto";
  std::string far_loss = tracker::LossTypeName(tracker::FarSourceOptions{}.loss);
  std::string sensor_offset = tracker::SensorOffsetOptions{}.window ? "on" : tracker::SensorOffsetOptions{}.batch ? "batch" : "off";
  std::string turn_onset_search =
      tracker::TrackerOptions{}.window_turn_onset_search == tracker::TrackerOptions::OnsetSearch::kFast ? "fast"
                                                                                                        : "full";
  std::string variance_factor_statistic =
      tracker::VarianceFactorOptions{}.statistic == tracker::VarianceFactorOptions::Statistic::kResiduals
          ? "residuals"
          : "sensor-means";
};

// `fixes_help` says where this program's single-sample fixes come from.
inline void AddTrackerOptions(CLI::App& app, TrackerFlags* f, const std::string& fixes_help) {
  tracker::TrackerOptions& t = f->options.track;
  tracker::TrackManagementOptions& m = f->options.management;
  app.add_option("--window", t.window_s, "sliding-window length, s")->capture_default_str();
  app.add_option("--solve-interval", t.window_solve_interval_s,
                 "solve each track's window once per this much data, s (0 = every epoch)")
      ->capture_default_str();
  app.add_option("--loss", f->loss, "robust loss on each sample: huber, cauchy or trivial")
      ->capture_default_str()
      ->check(CLI::IsMember({"huber", "cauchy", "trivial"}));
  app.add_option("--loss-scale", t.measurement_loss_scale_sigma, "robust loss scale, in sigmas of the sample residual")
      ->capture_default_str();
  app.add_option("--q-position", t.process.position_m_per_sqrt_s, "horizontal (x, y) position random walk, m/sqrt(s)")
      ->capture_default_str();
  app.add_option("--q-depth", t.process.depth_m_per_sqrt_s, "depth (z) random walk, m/sqrt(s)")->capture_default_str();
  AddOnOffOption(app, "--variance-factor", &f->options.variance_factor.enabled,
                 "window: scale each track's reported covariance by its window's chi2/dof when above "
                 "--variance-factor-quantile of chi2_dof/dof (on), or not (off); the rows' sigma only");
  app.add_option("--variance-factor-statistic", f->variance_factor_statistic,
                 "--variance-factor's chi2: every whitened residual (residuals) or each sensor's mean residual over "
                 "the window (sensor-means)")
      ->capture_default_str()
      ->check(CLI::IsMember({"residuals", "sensor-means"}));
  app.add_option("--variance-factor-quantile", f->options.variance_factor.quantile,
                 "--variance-factor applies above this quantile of chi2_dof/dof")
      ->capture_default_str();
  AddOnOffOption(app, "--batch-variance-factor", &t.batch_variance_factor.enabled,
                 "batch: scale each state's covariance by the chi2/dof of the sensors' mean whitened residuals over "
                 "the --batch-variance-factor-span centred on it when above --variance-factor-quantile of "
                 "chi2_dof/dof (on), or not (off); the rows' sigma only");
  AddOnOffOption(app, "--batch-variance-factor-with-offsets", &t.batch_variance_factor_with_offsets,
                 "batch: --batch-variance-factor also for a track whose sensor offsets were solved (on), or not: "
                 "there the offsets model the B misfit and their uncertainty is in the covariance (off: the far "
                 "ship's sigma accepted, but more rows overconfident beside another vessel)");
  app.add_option("--batch-variance-factor-span", t.batch_variance_factor_span_s,
                 "--batch-variance-factor's span, s")
      ->capture_default_str();
  app.add_option("--q-depth-weak", t.process.depth_weak_m_per_sqrt_s,
                 "depth random walk from an epoch whose measured tensors are all below --depth-weak-snr "
                 "sigma_T, m/sqrt(s) (0 = --q-depth everywhere)")
      ->capture_default_str();
  app.add_option("--depth-weak-snr", t.process.depth_weak_tensor_snr,
                 "tensor SNR below which an epoch does not observe the depth (--q-depth-weak)")
      ->capture_default_str();
  app.add_option("--q-speed", t.process.speed_mps_per_sqrt_s, "speed random walk, m/s/sqrt(s)")->capture_default_str();
  app.add_option("--q-heading", t.process.heading_rad_per_sqrt_s, "heading random walk, rad/sqrt(s)")
      ->capture_default_str();
  app.add_option("--q-turn-rate", t.process.turn_rate_radps_per_sqrt_s, "turn-rate random walk, rad/s/sqrt(s)")
      ->capture_default_str();
  app.add_option("--q-turn-rate-window", t.process.window_turn_rate_radps_per_sqrt_s,
                 "turn-rate random walk of the sliding window, rad/s/sqrt(s)")
      ->capture_default_str();
  app.add_option("--q-turn-rate-warmup", t.process.turn_rate_warmup_radps_per_sqrt_s,
                 "turn-rate random walk of the batch warm-up pass (0 = none), rad/s/sqrt(s)")
      ->capture_default_str();
  app.add_option("--turn-loss", f->turn_loss, "robust loss on turn-rate changes: huber, cauchy or trivial")
      ->capture_default_str()
      ->check(CLI::IsMember({"huber", "cauchy", "trivial"}));
  app.add_option("--turn-loss-scale", t.process.turn_rate_loss_scale_sigma, "turn-rate loss scale, in sigmas of one step")
      ->capture_default_str();
  app.add_flag("--window-turn-onset", t.window_turn_onset_model,
               "window: after a solve also solve the window with the batch's stiff turn-rate walk and one free turn "
               "onset (on a grid), and emit it if its data cost is at most --window-turn-onset-bic-params x 1/2 ln(n) "
               "above the default's and its jump of turn rate is at least --window-turn-onset-jump-sigmas sigma "
               "(off by default)");
  app.add_option("--window-turn-onset-bic-params", t.window_turn_onset_bic_params,
                 "window: the BIC penalty of --window-turn-onset, in parameters (1/2 ln n each)")
      ->capture_default_str();
  app.add_option("--window-turn-onset-search", f->turn_onset_search,
                 "window: onsets tried by --window-turn-onset: fast (near the previous solve's onset, else only when "
                 "the default's turn rate spans more than --window-turn-onset-trigger-sigmas x the stiff walk's sigma "
                 "over the window: a coarse grid then the fine grid next to its best) or full (every grid point and "
                 "'no onset' after every solve)")
      ->capture_default_str()
      ->check(CLI::IsMember({"fast", "full"}));
  app.add_option("--window-turn-onset-trigger-sigmas", t.window_turn_onset_trigger_sigmas,
                 "window: the fast search's trigger, in sigmas of the stiff walk over the window")
      ->capture_default_str();
  app.add_option("--window-turn-onset-trigger-noise", t.window_turn_onset_trigger_noise_sigmas,
                 "window: the fast search's trigger counts only if the default's turn-rate span is also at least this "
                 "many sigma of the stiff walk and of the default's own turn-rate sigma at the span's ends combined "
                 "(0 = off, the default)")
      ->capture_default_str();
  app.add_option("--window-turn-onset-coarse-grid", t.window_turn_onset_coarse_grid_s,
                 "window: the fast search's coarse grid of onsets when it has no previous onset, s")
      ->capture_default_str();
  app.add_option("--window-turn-onset-jump-sigmas", t.window_turn_onset_jump_sigmas,
                 "window: --window-turn-onset's onset is emitted only if its jump of turn rate is at least this many "
                 "sigma (0 = no guard)")
      ->capture_default_str();
  app.add_option("--init-from", f->init_from,
                 "fixes that start a track: auto (" + fixes_help +
                     " when they suffice, else its own TED+EGT on the samples), dipole_fix (" + fixes_help +
                     " only), samples (its own only)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "dipole_fix", "samples"}));
  app.add_option("--init-snr", t.init.min_tensor_snr,
                 "a sample gives an initiation fix if its tensor norm is at least this many sigma_T")
      ->capture_default_str();
  app.add_option("--gate-snr", m.gate_snr, "a track uses the sensors where its predicted signal SNR is at least this")
      ->capture_default_str();
  app.add_option("--detect-llr", m.detect_llr, "log-likelihood ratio of a detection (negated: of a miss) per epoch")
      ->capture_default_str();
  app.add_option("--confirm-m", m.confirm_m, "a new track is confirmed by M detections ...")->capture_default_str();
  app.add_option("--confirm-n", m.confirm_n, "... among its first N epochs")->capture_default_str();
  app.add_option("--max-miss", m.max_miss_s, "a track missed this long in a row ends, s")->capture_default_str();
  app.add_option("--max-coast", m.max_coast_s, "a track not detected this long ends, s")->capture_default_str();
  app.add_option("--confirm-tensor-snr", m.confirm_tensor_snr,
                 "a detection counts toward confirmation only if the track's predicted tensor SNR reaches this at one "
                 "of its sensors and it reduces their tensor chi-square (0 = off)")
      ->capture_default_str();
  app.add_option("--reach-tensor-snr", m.reach_tensor_snr,
                 "a track outside the sensors' bounding box whose predicted tensor SNR is below this at every sensor "
                 "is out of reach ...")
      ->capture_default_str();
  app.add_option("--out-of-reach", m.out_of_reach_s, "... and ends after this long out of reach, s (0 = off)")
      ->capture_default_str();
  app.add_option("--reach-shared-b-snr", m.reach_shared_b_snr,
                 "... unless its predicted B SNR is at least this at a sensor another live track gates (its field "
                 "still in that track's samples; 0 = off)")
      ->capture_default_str();
  app.add_option("--ghost-field", m.ghost_field_s,
                 "a track ended out of reach leaves its predicted field (a ghost: no row, no track) subtracted from "
                 "every sample, its uncertainty in their sigma, for at most this long, s (0 = off)")
      ->capture_default_str();
  app.add_option("--ghost-b-snr", m.ghost_b_snr,
                 "... while its predicted B SNR is at least this at some sensor")
      ->capture_default_str();
  cli::AddSwitchOption(app, "--pair-refit-excess", &m.pair_refit_excess,
                 "a pair's refit adds its coupling (the joint fit's marginal minus given-the-partner covariance) to "
                 "each refitted track's covariance for --window s after it (0/1; on)")
      ->capture_default_str();
  app.add_option("--foreign-b-ratio", m.foreign_b_ratio,
                 "a track held by its tensor (SNR >= --residual-start-snr at a sensor) does not take a sample where its "
                 "predicted tensor SNR is below --reach-tensor-snr and the B it leaves there is >= --gate-snr sigma_B "
                 "and more than this times its predicted B (another source's; 0 = off)")
      ->capture_default_str();
  app.add_option("--reacquire", m.reacquire_s,
                 "a newly confirmed track continues (takes the id of) a track ended at most this long before whose "
                 "state (x, y, speed, heading, both propagated) it gates by chi-square, with no other live track "
                 "closer to either, s (0 = off)")
      ->capture_default_str();
  app.add_option("--reacquire-gate", m.reacquire_gate_chi2,
                 "... the gate: chi-square (4 dof) of the two states")
      ->capture_default_str();
  app.add_option("--max-sigma-h", m.max_sigma_horizontal_m, "a track whose horizontal 1-sigma exceeds this ends, m")
      ->capture_default_str();
  app.add_option("--min-separation", m.min_separation_m,
                 "no new track this close to a live one; a track this close to an older one for --max-miss ends, m")
      ->capture_default_str();
  app.add_option("--max-chi2", m.max_chi2_per_dof, "poor fit (a miss): residual chi-square per residual above this ...")
      ->capture_default_str();
  app.add_option("--max-unexplained", m.max_unexplained,
                 "... and residual energy above this share of the signal's")
      ->capture_default_str();
  app.add_option("--poor-fit-tensor-snr", m.poor_fit_tensor_snr,
                 "... not counting a sample where the track's predicted tensor SNR is below this and the residual tensor's reaches it (another vessel's; 0 = off)")
      ->capture_default_str();
  app.add_option("--residual-start-snr", m.residual_start.tensor_snr,
                 "beside a live track, start a vessel from the residual (every track's field removed) at this tensor "
                 "SNR, jointly with the track (0 = off)")
      ->capture_default_str();
  app.add_option("--lone-start-fixes", m.residual_start.lone_min_fixes,
                 "with no live track, start a lone vessel at the residual start's tensor SNR from at least this many "
                 "single-sample fixes (0 = off)")
      ->capture_default_str();
  app.add_option("--lone-start-span", m.residual_start.lone_min_span_s,
                 "... spanning at least this many seconds")
      ->capture_default_str();
  cli::AddSwitchOption(app, "--lone-pair-start", &m.residual_start.lone_pair,
                 "with no live track and no lone start, start two weak vessels abreast by the two-dipole fit with "
                 "the lone start's SNR, fixes and span (0/1)")
      ->capture_default_str();
  cli::AddSwitchOption(app, "--excuse-beside", &m.excuse_beside,
                 "a track's misses do not count while a two-dipole fit beside it explains its samples with a "
                 "newcomer seen (its B and tensor, with tensor evidence) but too weak yet to start (0/1)")
      ->capture_default_str();
  app.add_option("--min-new-share", m.min_new_share,
                 "residual below this share of a track's predicted tensor is not offered to the initiator")
      ->capture_default_str();
  app.add_option("--evidence-gate", m.evidence_gate_chi2,
                 "a single-sample fix may go to a track if its innovation chi-square (3 dof) is at most this")
      ->capture_default_str();
  app.add_option("--evidence-snr", m.evidence_min_tensor_snr,
                 "... and the track's predicted tensor SNR at the fix's sensor at least this")
      ->capture_default_str();
  tracker::BackgroundOptions& b = f->options.background;
  AddOnOffOption(app, "--background", &b.enabled,
                 "each sensor's background B0 estimated with the tracks (on) or the fixed B0 (off)");
  app.add_option("--bg-rate-walk", b.rate_walk_T_per_s_per_sqrt_s,
                 "background: random walk of its rate of change, T/s/sqrt(s)")
      ->capture_default_str();
  app.add_option("--bg-level-walk", b.level_walk_T_per_sqrt_s, "background: random walk of its level, T/sqrt(s)")
      ->capture_default_str();
  app.add_option("--bg-gate", b.gate_chi2,
                 "background: a residual B with chi-square (3 axes) above this is down-weighted to it")
      ->capture_default_str();
  tracker::ClusterBackgroundOptions& c = f->options.cluster_background;
  AddOnOffOption(app, "--cluster-background", &c.enabled,
                 "each sensor's B0 offset estimated jointly with the tracks that see it, per window solve and batch "
                 "round (on), or the fixed B0 (off); not with --background on");
  app.add_option("--cbg-prior-sigma", c.prior_sigma_T, "cluster background: zero-mean prior of each offset, T")
      ->capture_default_str();
  app.add_option("--cbg-walk", c.walk_T_per_sqrt_s, "cluster background: random walk of each offset, T/sqrt(s)")
      ->capture_default_str();
  app.add_option("--cbg-tensor-gate", c.tensor_gate,
                 "cluster background: a sample whose residual tensor (whitened, |.|^2/9) exceeds this is not used")
      ->capture_default_str();
  app.add_option("--cbg-field-share", c.track_field_share,
                 "cluster background: the tracks' predicted B taken as uncertain by this share of its norm")
      ->capture_default_str();
  app.add_option("--cbg-rate-walk", c.rate_walk_T_per_s_per_sqrt_s,
                 "cluster background: random walk of each offset's rate, T/s/sqrt(s) (0 = a level walk alone)")
      ->capture_default_str();
  app.add_option("--cbg-occupied-snr", c.occupied_tensor_snr,
                 "cluster background: a sample where the tracks' predicted tensor SNR is at least this does not enter "
                 "the offset (0 = every sample)")
      ->capture_default_str();
  tracker::FarSourceOptions& fs = f->options.far_source;
  app.add_option("--far-source", f->far_source,
                 "a far ship as one dipole outside the array, fitted over the recent samples minus the tracks' B and "
                 "its B removed from every sample (on), or nothing removed (off); not with a background model; auto: "
                 "on unless --background or --cluster-background is on")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "on", "off"}));
  app.add_option("--far-window", fs.window_s, "far source: span of recent samples each fit is made over, s")
      ->capture_default_str();
  app.add_option("--far-extent-factor", fs.extent_factor,
                 "far source: it stays this many times the array's horizontal half-extent (plus --far-margin) "
                 "from the sensors' centroid")
      ->capture_default_str();
  app.add_option("--far-margin", fs.margin_m, "far source: added to that distance, m")->capture_default_str();
  app.add_option("--far-share", fs.model_share,
                 "far source: its removed B taken as uncertain by this share of its norm (added to sigma_B)")
      ->capture_default_str();
  app.add_option("--far-unexplained-sigma", fs.unexplained_sigma_T,
                 "far source: the far field its model does not explain, added to sigma_B of every sample whether or "
                 "not a fit is accepted, T per axis (0 = off)")
      ->capture_default_str();
  app.add_option("--far-unexplained-fix-search", fs.unexplained_in_fix_search,
                 "far source: that allowance also in the initiator's searches (single-sample fixes, pair start; 1, "
                 "the default) or only in the fits (0: the single start's moment fit, the association, the solves)")
      ->capture_default_str();
  AddOnOffOption(app, "--far-drift", &fs.drift.enabled,
                 "far source: each sensor's drift (a line in time over the far source's window) fitted with it and "
                 "removed (on), or the fixed B0 (off)");
  app.add_option("--far-drift-tensor-window", fs.drift.tensor_mean_window_s,
                 "far source's drift: a sample enters a sensor's line only while that sensor's residual tensor, "
                 "averaged over this many seconds, is within --far-drift-tensor-gate (an untracked near vessel), s "
                 "(0 = off)")
      ->capture_default_str();
  AddOnOffOption(app, "--far-drift-batch", &fs.drift.batch_refit,
                 "far source's drift: the batch refits each sensor's line over the whole pass with its refined tracks "
                 "(on) or removes the finder's causal line (off)");
  app.add_option("--far-drift-min-span", fs.drift.min_span_s,
                 "far source's drift: a sensor's line is fitted (and removed) only once its quiet samples span this "
                 "long, s")
      ->capture_default_str();
  app.add_option("--far-drift-confirm-rate", fs.drift.confirm_min_rate_T_per_s,
                 "far source's drift: a sensor's line is removed only once its rate is at least this, T/s (0 = any)")
      ->capture_default_str();
  app.add_option("--far-drift-tensor-gate", fs.drift.tensor_mean_gate,
                 "far source's drift: the gate on that mean (whitened, |sum|^2 / sum of variances / 9; noise alone ~ 1)")
      ->capture_default_str();
  app.add_option("--far-max-interval", fs.max_interval_s,
                 "far source: while its fits are refused (no ship-like source), the interval to the next fit doubles "
                 "up to this, s (1 = a fit every second, no back-off)")
      ->capture_default_str();
  app.add_option("--far-along", fs.along_extent_m,
                 "far source: its start grid's along-line positions reach this far from the line's closest point, m")
      ->capture_default_str();
  AddOnOffOption(app, "--far-grid-when-refused", &fs.grid_when_refused,
                 "far source: after a refused fit, search the start grid again (on) or only when the previous fit "
                 "no longer fits (off)");
  app.add_option("--far-bound-accept-moment", fs.bound_accept_moment_Am2,
                 "far source: a fit pressed against its bound is still removed when its moment is at least this "
                 "(a ship far along its line), A m^2 (0 = off: every fit at the bound is refused)")
      ->capture_default_str();
  app.add_option("--far-max-moment", fs.max_moment_Am2,
                 "far source: a fit whose moment is above this is not removed (no ship is that strong; a drift of "
                 "every sensor's B0 is mimicked by a huge source far off), A m^2 (0 = off: any moment is removed)")
      ->capture_default_str();
  AddOnOffOption(app, "--far-back-predict", &fs.back_predict_new_tracks,
                 "far source: at each fit, a kept sample older than a live track's start gets that track's field "
                 "predicted back to its time (its B subtracted, or the sample left out where its tensor would have "
                 "occupied it or its B is >= 3 sigma_B; nothing where a track within the tracks' min separation was "
                 "live when the sample was kept: that vessel's B is already out) (on), or is fitted as it was kept "
                 "(off)");
  app.add_option("--sensor-offset", f->sensor_offset,
                 "each track's window and batch solve gives every sensor a B offset (world NED) as a nuisance, constant "
                 "over the window or over one --sensor-offset-segment of the batch, with a zero-mean prior from the "
                 "drift model (on), the same in the batch's solve only (behind --sensor-offset-score-test), the "
                 "window going on with B0 as it is (batch), or takes B0 as it is (off)")
      ->capture_default_str()
      ->check(CLI::IsMember({"on", "batch", "off"}));
  AddOnOffOption(app, "--sensor-offset-quiet", &t.sensor_offset.quiet,
                 "sensor offset (window, with --sensor-offset on; magnav track): each sensor's offset owned by the "
                 "sensor: the median of the B it gave while no track's field (nor an untracked near source) was "
                 "there, walked at --sensor-offset-rate since, as every track's prior (taken as it is below "
                 "--sensor-offset-min-tensor-snr) (on), or as the other sensor-offset flags say (off)");
  AddOnOffOption(app, "--sensor-offset-quiet-rate", &t.sensor_offset.quiet_rate,
                 "sensor offset (with --sensor-offset-quiet on): each sensor's quiet offset is a line in time, its "
                 "rate from the medians of the older and newer halves of its last --sensor-offset-quiet-rate-span s of "
                 "quiet samples (bounded by --sensor-offset-rate), predicted to the window with its sigma growing (on), "
                 "or the median walked at --sensor-offset-rate (off)");
  app.add_option("--sensor-offset-quiet-rate-span", t.sensor_offset.quiet_rate_span_s,
                 "sensor offset (with --sensor-offset-quiet-rate on): the span of quiet samples the line is fitted "
                 "over, s")
      ->capture_default_str();
  AddOnOffOption(app, "--sensor-offset-quiet-approach", &t.sensor_offset.quiet_approach,
                 "sensor offset (with --sensor-offset-quiet on): when a track is confirmed, its back-predicted field is taken "
                 "out of every sensor's stored quiet samples (dropped where it would have made the sensor not quiet, "
                 "else its B subtracted) (on), or the store kept as it is (off)");
  AddOnOffOption(app, "--sensor-offset-carry", &t.sensor_offset.carry,
                 "sensor offset (window, with --sensor-offset on): each sensor's offset carried from window to window "
                 "(the samples that left the window, the walk of --sensor-offset-rate since) as its prior (on), or a "
                 "zero-mean prior in every window (off)");
  AddOnOffOption(app, "--window-offset-score-test", &t.sensor_offset.window_score_test,
                 "sensor offset (window, with --sensor-offset on or --window-offset-lines on): a track's window "
                 "solves its offsets only from the solve where its B residuals call for them (the batch's score test, "
                 "per sensor over the window) to the track's end (on), or from the start (off)");
  app.add_option("--window-offset-score-persist", t.sensor_offset.window_score_persist_s,
                 "--window-offset-score-test: it latches only once it has fired at every window solve for this long, "
                 "s, the window's prior then from the leaving samples' tensors alone (0 = at its first firing)")
      ->capture_default_str();
  AddOnOffOption(app, "--window-offset-lines", &t.sensor_offset.window_lines,
                 "each track's window solve gives every sensor a B offset that is a line in time over the window "
                 "(level and rate; an untracked vessel's B changing within the window) as a nuisance (on; the batch "
                 "follows --sensor-offset alone; not with --sensor-offset-carry), or as --sensor-offset says (off)");
  app.add_option("--window-offset-rate-sigma", t.sensor_offset.line_rate_sigma_T_per_s,
                 "--window-offset-lines: the zero-mean prior sigma of each sensor's rate, T/s per axis")
      ->capture_default_str();
  app.add_option("--sensor-offset-min-tensor-snr", t.sensor_offset.min_tensor_snr,
                 "sensor offset: only sensors where the track's predicted tensor SNR reaches this in the window (batch: "
                 "the solved span) get an offset; the others keep B0 (0 = every sensor)")
      ->capture_default_str();
  app.add_option("--sensor-offset-rate", t.sensor_offset.max_rate_T_per_s,
                 "sensor offset: the drift rate bound of its prior, sigma = hypot(--sensor-offset-floor, rate * "
                 "(t - B0's time 0)), T/s per axis")
      ->capture_default_str();
  app.add_option("--sensor-offset-floor", t.sensor_offset.floor_T, "sensor offset: its prior's sigma at t = 0, T")
      ->capture_default_str();
  app.add_option("--sensor-offset-segment", t.sensor_offset.segment_s,
                 "sensor offset: the batch's offsets are constant over segments this long, s")
      ->capture_default_str();
  app.add_option("--sensor-offset-passes", t.sensor_offset.passes,
                 "sensor offset: rounds of the offsets' update and the track's solve after each window solve")
      ->capture_default_str();
  app.add_option("--sensor-offset-batch-passes", t.sensor_offset.batch_passes,
                 "sensor offset: at most this many rounds after each stage of the batch's growing solve")
      ->capture_default_str();
  AddOnOffOption(app, "--sensor-offset-score-test", &t.sensor_offset.batch_score_test,
                 "sensor offset (batch): the batch is solved without offsets first and again with them only when "
                 "its B residual means per sensor and --sensor-offset-segment call for them (chi2 above the "
                 "--variance-factor-quantile point; the track file's summary gives it) (on), or always with them (off)");
  AddOnOffOption(app, "--sensor-offset-joint", &t.sensor_offset.batch_joint,
                 "sensor offset (batch): after the rounds of offsets and track, one joint solve of the track and "
                 "every offset (on), or the rounds' end as the solution (off)");
  app.add_option("--far-loss", f->far_loss,
                 "far source: the fit's robust loss on the whitened B residual (cauchy, huber or trivial)")
      ->capture_default_str();
}

// The options the flags give. Throws InputError naming the flag for a bad
// choice, and the option for an inconsistent set (IsValid).
inline tracker::MultiTrackerOptions ApplyTrackerFlags(const TrackerFlags& f) {
  tracker::MultiTrackerOptions o = f.options;
  if (!tracker::ParseLossType(f.loss, &o.track.measurement_loss)) {
    throw InputError("--loss: expected huber, cauchy or trivial, got '" + f.loss + "'");
  }
  if (!tracker::ParseLossType(f.turn_loss, &o.track.process.turn_rate_loss)) {
    throw InputError("--turn-loss: expected huber, cauchy or trivial, got '" + f.turn_loss + "'");
  }
  if (!tracker::ParseInitSource(f.init_from, &o.track.init.source)) {
    throw InputError("--init-from: expected auto, dipole_fix or samples, got '" + f.init_from + "'");
  }
  o.far_source.enabled = f.far_source == "auto"
                            ? tracker::FarSourceOptions{}.enabled && !o.background.enabled && !o.cluster_background.enabled
                            : f.far_source == "on";
  if (!tracker::ParseLossType(f.far_loss, &o.far_source.loss)) {
    throw InputError("--far-loss: expected huber, cauchy or trivial, got '" + f.far_loss + "'");
  }
  o.track.sensor_offset.window = f.sensor_offset == "on";
  o.track.sensor_offset.batch = f.sensor_offset == "on" || f.sensor_offset == "batch";
  if (f.turn_onset_search != "fast" && f.turn_onset_search != "full") {
    throw InputError("--window-turn-onset-search: expected fast or full, got '" + f.turn_onset_search + "'");
  }
  o.track.window_turn_onset_search = f.turn_onset_search == "fast" ? tracker::TrackerOptions::OnsetSearch::kFast
                                                                   : tracker::TrackerOptions::OnsetSearch::kFull;
  o.track.batch_variance_factor.quantile = o.variance_factor.quantile;  // one flag for both
  o.variance_factor.statistic = f.variance_factor_statistic == "residuals"
                                    ? tracker::VarianceFactorOptions::Statistic::kResiduals
                                    : tracker::VarianceFactorOptions::Statistic::kSensorMeans;
  std::string why;
  if (!o.IsValid(&why)) throw InputError("tracker options: " + why);
  return o;
}

}  // namespace magnav::cli
