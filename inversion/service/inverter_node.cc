#include "inverter_node.h"

#include <cmath>

#include "magnav/dds/convert.h"

namespace magnav::inversion {

namespace {
dds::msg::FixMethod MsgMethod(Method m) {
  switch (m) {
    case Method::kTed:
      return dds::msg::METHOD_TED;
    case Method::kTedEgt:
      return dds::msg::METHOD_TED_EGT;
    case Method::kEgt:
      return dds::msg::METHOD_EGT;
  }
  return dds::msg::METHOD_OTHER;
}

std::array<double, 3> Arr(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
}  // namespace

dds::msg::DipoleFix ToMsg(const DipoleFix& fix, std::uint64_t stamp_ns, std::uint64_t sample_seq,
                          dds::msg::FixMethod method) {
  dds::msg::DipoleFix m;
  m.sensor_id(fix.sensor_id);
  m.stamp_ns(stamp_ns);
  m.sample_seq(sample_seq);
  m.method(method);
  m.valid(fix.valid);
  m.reason(RejectReasonName(fix.reason));
  m.position(Arr(fix.p_DinW));
  m.has_moment(fix.has_moment && fix.m_W.allFinite());
  m.moment(m.has_moment() ? Arr(fix.m_W) : std::array<double, 3>{0, 0, 0});
  m.condition_number(fix.cond);
  std::array<double, 9> cov{};
  if (std::isfinite(fix.position_sigma_m)) {
    const double v = fix.position_sigma_m * fix.position_sigma_m;
    cov[0] = cov[4] = cov[8] = v;  // isotropic first-order 1-σ (see inverter.h)
  }
  m.covariance(cov);
  return m;
}

InverterNode::InverterNode(dds::Node& node, const InverterOptions& options)
    : engine_(std::in_place_type<Inverter>, options), method_(MsgMethod(options.method)) {
  Start(node);
}

InverterNode::InverterNode(dds::Node& node, const MonteCarloTrackerOptions& options)
    : engine_(std::in_place_type<MonteCarloTracker>, options), method_(dds::msg::METHOD_MC) {
  Start(node);
}

void InverterNode::Start(dds::Node& node) {
  writer_ = node.CreateWriter<dds::msg::DipoleFix>();
  reader_ = node.CreateReader<dds::msg::GradiometerSample>(
      [this](const dds::msg::GradiometerSample& m, const auto&) { OnSample(m); });
}

void InverterNode::OnSample(const dds::msg::GradiometerSample& m) {
  const GradiometerSample s = dds::FromMsg(m);
  std::lock_guard<std::mutex> lk(mu_);
  const DipoleFix fix = std::visit([&](auto& engine) { return engine.Process(s); }, engine_);
  writer_->Write(ToMsg(fix, m.stamp_ns(), m.seq(), method_));
}

}  // namespace magnav::inversion
