#include "magnav/dds/regional_field_source.h"

#include <spdlog/spdlog.h>

#include "magnav/core/csv.h"

namespace magnav::dds {

namespace {
}  // namespace

RegionalFieldSource::RegionalFieldSource(std::string service, const Eigen::Vector3d& B0_W)
    : service_(std::move(service)), fixed_(B0_W) {}

RegionalFieldSource::RegionalFieldSource(std::string service, const RegionalFieldOptions& options)
    : service_(std::move(service)), options_(options), estimator_(std::in_place, options) {}

std::optional<Eigen::Vector3d> RegionalFieldSource::For(const GradiometerSample& s) {
  if (fixed_) return fixed_;
  std::lock_guard<std::mutex> lk(mu_);
  const auto status = estimator_->Add(s);
  if (status == RegionalFieldEstimator::Status::kBecameReady) {
    spdlog::info("{}: sensor {}: B0 estimated {} T from {} quiet samples up to t = {} s", service_, s.sensor_id,
                 FormatVec3(*estimator_->B0(s.sensor_id)), estimator_->num_samples(s.sensor_id), s.t_s);
  } else if (status == RegionalFieldEstimator::Status::kUnknownSigma &&
             unknown_sigma_logged_.insert(s.sensor_id).second) {
    spdlog::warn("{}: sensor {}: its samples carry no sigma_B/sigma_T and none was given (--sigma-b, --sigma-t): "
                 "B0 cannot be estimated, give --b0",
                 service_, s.sensor_id);
  }
  auto B0 = estimator_->B0(s.sensor_id);
  if (!B0) ++waiting_;
  return B0;
}

std::string RegionalFieldSource::Describe() const {
  if (fixed_) return "B0 = " + FormatVec3(*fixed_) + " T (given)";
  return "B0 estimated per sensor from quiet stretches (" + FormatNumber(options_.window_s) +
         " s with the tensor at noise level and a steady field); until a sensor's B0 is known its samples "
         "are not used";
}

std::unique_ptr<RegionalFieldSource> MakeRegionalFieldSource(const std::string& service,
                                                             const std::optional<Eigen::Vector3d>& given,
                                                             double sigma_B_fallback, double sigma_T_fallback) {
  if (given) return std::make_unique<RegionalFieldSource>(service, *given);
  RegionalFieldOptions options;
  options.sigma_B_fallback = sigma_B_fallback;
  options.sigma_T_fallback = sigma_T_fallback;
  return std::make_unique<RegionalFieldSource>(service, options);
}

}  // namespace magnav::dds
