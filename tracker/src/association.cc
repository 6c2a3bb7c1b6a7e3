#include "magnav/tracker/association.h"

#include <cmath>

#include "magnav/tracker/initialize.h"
#include "other_fields.h"

namespace magnav::tracker {

FieldPrediction PredictAtSample(const CtState<double>& state, const Eigen::Vector3d& m_B_Am2,
                                const GradiometerSample& sample, const TrackerOptions& options) {
  FieldPrediction p;
  PredictedField(state, m_B_Am2, sample.p_SinW, &p.B, &p.T);
  const double sb = SigmaB(sample, options), st = SigmaT(sample, options);
  p.snr = std::sqrt(p.B.squaredNorm() / (sb * sb) + p.T.squaredNorm() / (st * st));
  if (!std::isfinite(p.snr)) p.snr = 0.0;
  return p;
}

std::vector<TrackAssociation> AssociateEpoch(const Epoch& epoch, const std::vector<TrackPrediction>& predictions,
                                             const Eigen::Vector3d& B0_W, const MultiTrackerOptions& options) {
  const TrackManagementOptions& mg = options.management;
  const std::size_t n = epoch.samples.size();
  std::vector<TrackAssociation> out(predictions.size());
  for (std::size_t i = 0; i < predictions.size(); ++i) {
    TrackAssociation& a = out[i];
    a.mine.t_s = epoch.t_s;
    if (predictions[i].valid) {
      for (std::size_t j = 0; j < n; ++j) {
        if (!(predictions[i].at[j].snr >= mg.gate_snr)) continue;
        GradiometerSample s = epoch.samples[j];
        Eigen::Vector3d B_others = Eigen::Vector3d::Zero();
        Eigen::Matrix3d T_others = Eigen::Matrix3d::Zero();
        bool any_other = false;
        for (std::size_t k = 0; k < predictions.size(); ++k) {
          if (k == i || !predictions[k].valid) continue;
          B_others += predictions[k].at[j].B;
          T_others += predictions[k].at[j].T;
          any_other = true;
        }
        if (any_other) {
          RemoveOtherFields(B_others, T_others, SigmaB(s, options.track), SigmaT(s, options.track), &s);
        }
        const double sb = SigmaB(s, options.track), st = SigmaT(s, options.track);
        const Eigen::Vector3d dB = s.B - B0_W;
        const FieldPrediction& p = predictions[i].at[j];
        const double m2 = dB.squaredNorm() / (sb * sb) + s.T.squaredNorm() / (st * st);
        const double r2 = (dB - p.B).squaredNorm() / (sb * sb) + (s.T - p.T).squaredNorm() / (st * st);
        if (std::isfinite(m2) && std::isfinite(r2)) {
          a.llr += 0.5 * (m2 - r2);
          a.sum_m2 += m2;
          a.sum_r2 += r2;
        }
        a.mine.samples.push_back(std::move(s));
      }
    }
    // Explained share: a track whose prediction leaves most of a strong
    // signal unexplained (another, untracked source dominates its sensors,
    // or it has drifted off its vessel) is not detected but missed.
    const double dof = 8.0 * static_cast<double>(a.mine.samples.size());
    a.poor_fit = dof > 0.0 && a.sum_r2 > mg.max_chi2_per_dof * dof && a.sum_r2 > mg.max_unexplained * a.sum_m2;
    a.detected = a.llr >= mg.detect_llr && !a.poor_fit;
    a.missed = a.llr <= -mg.detect_llr || a.poor_fit;
  }
  return out;
}

}  // namespace magnav::tracker
