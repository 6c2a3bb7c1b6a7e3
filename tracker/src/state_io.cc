#include "state_io.h"

namespace magnav::tracker::internal {

Eigen::MatrixXd GetMatrix(StateReader& r, Eigen::Index rows, Eigen::Index cols) {
  Eigen::MatrixXd m = r.Matrix(static_cast<std::size_t>(rows), static_cast<std::size_t>(cols));
  if (m.rows() != rows || m.cols() != cols) throw CheckpointError("corrupt: a matrix of another size");
  return m;
}

void Put(StateWriter& w, const GradiometerSample& s) {
  w.U32(s.sensor_id);
  w.F64(s.t_s);
  w.Matrix(s.p_SinW);
  w.Matrix(s.B);
  w.Matrix(s.T);
  w.F64(s.sigma_B);
  w.F64(s.sigma_T);
}

void Get(StateReader& r, GradiometerSample* s) {
  s->sensor_id = r.U32();
  s->t_s = r.F64();
  s->p_SinW = GetMatrix(r, 3, 1);
  s->B = GetMatrix(r, 3, 1);
  s->T = GetMatrix(r, 3, 3);
  s->sigma_B = r.F64();
  s->sigma_T = r.F64();
}

void Put(StateWriter& w, const Epoch& e) {
  w.F64(e.t_s);
  w.U64(e.samples.size());
  for (const auto& s : e.samples) Put(w, s);
}

void Get(StateReader& r, Epoch* e) {
  e->t_s = r.F64();
  e->samples.resize(r.Count(kMaxStateCount));
  for (auto& s : e->samples) Get(r, &s);
}

void Put(StateWriter& w, const DipoleFix& f) {
  w.U32(f.sensor_id);
  w.F64(f.t_s);
  w.U8(f.valid ? 1 : 0);
  w.I64(static_cast<std::int64_t>(f.reason));
  w.Matrix(f.p_DinW);
  w.Matrix(f.r_DtoS);
  w.Matrix(f.m_W);
  w.U8(f.has_moment ? 1 : 0);
  w.F64(f.cond);
  w.F64(f.snr);
  w.Matrix(f.cov_p_DinW);
  w.F64(f.position_sigma_3d_m);
}

void Get(StateReader& r, DipoleFix* f) {
  f->sensor_id = r.U32();
  f->t_s = r.F64();
  f->valid = r.U8() != 0;
  f->reason = static_cast<inversion::RejectReason>(r.I64());
  f->p_DinW = GetMatrix(r, 3, 1);
  f->r_DtoS = GetMatrix(r, 3, 1);
  f->m_W = GetMatrix(r, 3, 1);
  f->has_moment = r.U8() != 0;
  f->cond = r.F64();
  f->snr = r.F64();
  f->cov_p_DinW = GetMatrix(r, 3, 3);
  f->position_sigma_3d_m = r.F64();
}

void Put(StateWriter& w, const Summary& s) {
  for (bool b : {s.initialized, s.usable, s.converged, s.init_from_external_fixes, s.covariance_ok}) w.U8(b ? 1 : 0);
  for (int i : {s.num_epochs, s.num_samples, s.num_init_fixes, s.iterations, s.num_rejected_samples,
                s.num_dropped_factors}) {
    w.I64(i);
  }
  for (double d : {s.initial_cost, s.final_cost, s.solve_time_s, s.covariance_time_s, s.total_time_s}) w.F64(d);
  w.Bytes(s.message);
}

void Get(StateReader& r, Summary* s) {
  for (bool* b : {&s->initialized, &s->usable, &s->converged, &s->init_from_external_fixes, &s->covariance_ok}) {
    *b = r.U8() != 0;
  }
  for (int* i : {&s->num_epochs, &s->num_samples, &s->num_init_fixes, &s->iterations, &s->num_rejected_samples,
                 &s->num_dropped_factors}) {
    *i = static_cast<int>(r.I64());
  }
  for (double* d : {&s->initial_cost, &s->final_cost, &s->solve_time_s, &s->covariance_time_s, &s->total_time_s}) {
    *d = r.F64();
  }
  s->message = r.Bytes(kMaxStateCount);
}

std::string OptionsBytes(const Eigen::Vector3d& B0_W, const MultiTrackerOptions& o) {
  StateWriter w;
  w.Matrix(B0_W);
  const TrackerOptions& t = o.track;
  const ProcessNoise& q = t.process;
  const InitOptions& i = t.init;
  const TrackManagementOptions& g = o.management;
  for (double d :
       {t.default_sigma_B_T, t.default_sigma_T_Tpm, t.measurement_loss_scale_sigma, q.position_m_per_sqrt_s,
        q.depth_m_per_sqrt_s,
        q.speed_mps_per_sqrt_s, q.heading_rad_per_sqrt_s, q.turn_rate_radps_per_sqrt_s, q.turn_rate_loss_scale_sigma,
        q.turn_rate_warmup_radps_per_sqrt_s, q.window_turn_rate_radps_per_sqrt_s, i.min_tensor_snr, i.min_span_s,
        i.span_s, i.outlier_threshold_mad, i.cluster_gate_m, i.max_dipole_misfit, t.epoch_tolerance_s, t.function_tolerance,
        t.intermediate_function_tolerance, t.gradient_tolerance, t.parameter_tolerance, t.batch_growth_factor,
        t.window_s, t.window_solve_interval_s, t.window_function_tolerance, g.gate_snr, g.detect_llr,
        g.max_chi2_per_dof, g.max_unexplained, g.poor_fit_tensor_snr, g.min_new_share, g.max_miss_s, g.max_coast_s,
        g.max_sigma_horizontal_m, g.min_separation_m, g.init_interval_s, g.evidence_gate_chi2,
        g.evidence_min_tensor_snr, g.pair_refit_s, g.joint_start_s, g.confirm_tensor_snr, g.reach_tensor_snr,
        g.out_of_reach_s, g.reach_shared_b_snr, g.ghost_field_s, g.ghost_b_snr, g.foreign_b_ratio, g.reacquire_s, g.reacquire_gate_chi2, o.batch_gate_snr, o.batch_extension_step_s,
        o.background.rate_walk_T_per_s_per_sqrt_s, o.background.level_walk_T_per_sqrt_s,
        o.background.initial_sigma_T, o.background.initial_rate_sigma_T_per_s, o.background.gate_chi2,
        o.background.occupied_tensor_chi2, o.background.occupied_average_s, o.cluster_background.prior_sigma_T,
        o.cluster_background.walk_T_per_sqrt_s, o.cluster_background.tensor_gate,
        o.cluster_background.track_field_share, o.cluster_background.occupied_tensor_snr,
        o.cluster_background.rate_walk_T_per_s_per_sqrt_s, o.cluster_background.prior_rate_sigma_T_per_s}) {
    w.F64(d);
  }
  for (std::int64_t n :
       {static_cast<std::int64_t>(t.tensor_noise_trace_free), static_cast<std::int64_t>(t.measurement_loss),
        static_cast<std::int64_t>(q.turn_rate_loss), static_cast<std::int64_t>(i.source),
        static_cast<std::int64_t>(i.min_fixes), static_cast<std::int64_t>(t.max_num_iterations),
        static_cast<std::int64_t>(t.batch_solver), static_cast<std::int64_t>(t.window_max_num_iterations),
        static_cast<std::int64_t>(t.window_solver), static_cast<std::int64_t>(t.compute_covariance),
        static_cast<std::int64_t>(t.covariance_method), static_cast<std::int64_t>(g.confirm_m),
        static_cast<std::int64_t>(g.confirm_n), static_cast<std::int64_t>(o.batch_rounds),
        static_cast<std::int64_t>(o.background.enabled), static_cast<std::int64_t>(o.cluster_background.enabled),
        static_cast<std::int64_t>(g.backfill_start)}) {
    w.I64(n);
  }
  w.F64(g.residual_start.tensor_snr);
  w.F64(g.residual_start.track_share);
  w.F64(g.residual_start.max_track_shift_m);
  w.I64(static_cast<std::int64_t>(g.residual_start.backfill_older));
  // The far source and the variance factor change every estimate or σ that
  // follows: a checkpoint made with other settings is another configuration.
  const FarSourceOptions& f = o.far_source;
  w.I64(static_cast<std::int64_t>(f.enabled));
  w.I64(static_cast<std::int64_t>(f.max_samples));
  for (double d : {f.window_s, f.solve_interval_s, f.sample_interval_s, f.min_span_s, f.extent_factor, f.margin_m,
                   f.max_range_m, f.max_height_m, f.loss_sigmas, f.tensor_gate, f.occupied_tensor_snr, f.model_share,
                   f.min_field_T, f.min_moment_Am2, f.bound_slack_m, f.max_interval_s, f.along_extent_m,
                   f.along_step_m}) {
    w.F64(d);
  }
  w.I64(static_cast<std::int64_t>(f.drift.enabled));
  w.I64(static_cast<std::int64_t>(f.drift.min_samples));
  for (double d : {f.drift.rate_prior_sigma_T_per_s, f.drift.huber_sigmas, f.drift.reject_sigmas, f.drift.max_rate_T_per_s,
                   f.drift.occupied_B_sigmas, f.drift.min_span_s, f.drift.window_s,
                   f.drift.sample_interval_s}) {
    w.F64(d);
  }
  w.I64(static_cast<std::int64_t>(f.grid_when_refused));
  w.I64(static_cast<std::int64_t>(f.loss));
  w.F64(f.unexplained_sigma_T);
  w.I64(static_cast<std::int64_t>(f.unexplained_in_fix_search));
  w.F64(o.track.init.fix_sigma_B_allowance_T);
  w.F64(f.bound_accept_moment_Am2);
  w.I64(static_cast<std::int64_t>(f.back_predict_new_tracks));
  w.F64(f.max_moment_Am2);
  const VarianceFactorOptions& v = o.variance_factor;
  w.I64(static_cast<std::int64_t>(v.enabled));
  w.I64(static_cast<std::int64_t>(v.statistic));
  w.F64(v.quantile);
  w.F64(v.max_factor);
  w.I64(static_cast<std::int64_t>(g.excuse_beside));
  w.I64(static_cast<std::int64_t>(g.backfill_single));
  w.I64(static_cast<std::int64_t>(g.residual_start.lone_min_fixes));
  w.F64(g.residual_start.lone_min_span_s);
  w.I64(static_cast<std::int64_t>(g.residual_start.lone_pair));
  w.I64(static_cast<std::int64_t>(g.pair_refit_excess));
  // The sensor offsets change every estimate, and the window's checkpoint
  // holds them only when they are on.
  // The batch's switch is not written: the batch is not checkpointed.
  const SensorOffsetOptions& so = t.sensor_offset;
  w.I64(static_cast<std::int64_t>(so.window));
  w.I64(static_cast<std::int64_t>(so.passes));
  w.I64(static_cast<std::int64_t>(so.batch_passes));
  w.I64(static_cast<std::int64_t>(so.carry));
  w.F64(so.min_tensor_snr);
  w.I64(static_cast<std::int64_t>(so.quiet));
  w.I64(static_cast<std::int64_t>(so.quiet_min_samples));
  w.F64(so.quiet_span_s);
  w.F64(so.quiet_tensor_mean_s);
  w.I64(static_cast<std::int64_t>(so.quiet_rate));
  w.F64(so.quiet_rate_span_s);
  w.I64(static_cast<std::int64_t>(so.quiet_approach));
  for (double d : {so.max_rate_T_per_s, so.floor_T, so.b0_time_s, so.segment_s, so.tolerance_T}) w.F64(d);
  w.I64(static_cast<std::int64_t>(so.window_lines));
  w.F64(so.line_rate_sigma_T_per_s);
  w.I64(static_cast<std::int64_t>(so.window_score_test));
  if (so.window_score_persist_s > 0.0) w.F64(so.window_score_persist_s);  // written only when on
  // The window's turn-onset model changes the rows it emits; the batch's
  // other-field covariance its σ.
  w.I64(static_cast<std::int64_t>(t.window_turn_onset_model));
  w.I64(static_cast<std::int64_t>(t.window_turn_onset_iterations));
  w.F64(t.window_turn_onset_grid_s);
  w.F64(t.window_turn_onset_bic_params);
  w.I64(static_cast<std::int64_t>(t.window_turn_onset_search));
  for (double d : {t.window_turn_onset_trigger_sigmas, t.window_turn_onset_coarse_grid_s,
                   t.window_turn_onset_jump_sigmas, t.window_turn_onset_trigger_noise_sigmas}) {
    w.F64(d);
  }
  w.I64(static_cast<std::int64_t>(o.batch_other_field_covariance));
  return w.bytes();
}

}  // namespace magnav::tracker::internal
