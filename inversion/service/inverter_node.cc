#include "inverter_node.h"

#include <cmath>

#include "magnav/core/error.h"
#include "magnav/dds/convert_inversion.h"

namespace magnav::inversion {

namespace {
template <typename T>
const T& ZeroB0(const T& options, const Vec3& B0_W) {
  if (!B0_W.isZero(0.0)) throw InputError("inverter node: B0 comes from its RegionalFieldSource; set B0_W = 0");
  return options;
}
}  // namespace

InverterNode::InverterNode(dds::Node& node, const InverterOptions& options,
                           std::unique_ptr<dds::RegionalFieldSource> b0)
    : b0_(std::move(b0)),
      engine_(std::in_place_type<Inverter>, ZeroB0(options, options.B0_W)),
      method_(dds::FixMethodOf(options.method)) {
  Start(node);
}

InverterNode::InverterNode(dds::Node& node, const MonteCarloTrackerOptions& options,
                           std::unique_ptr<dds::RegionalFieldSource> b0)
    : b0_(std::move(b0)),
      engine_(std::in_place_type<MonteCarloTracker>, ZeroB0(options, options.init_inverter.B0_W)),
      method_(dds::FixMethod::kMc) {
  Start(node);
}

void InverterNode::Start(dds::Node& node) {
  repeats_.SetLogName("magnav-inverter: magnav/gradiometer sensor");
  writer_ = node.CreateWriter<dds::msg::DipoleFix>();
  reader_ = node.CreateReader<dds::msg::GradiometerSample>(
      [this](const dds::msg::GradiometerSample& m, const auto& info) { OnSample(m, info); });
}

void InverterNode::OnSample(const dds::msg::GradiometerSample& m, const dds::fdds::SampleInfo& info) {
  // A sample seen before (a restarted producer's history) already has its fix.
  if (!repeats_.First(m, info)) return;
  for (const auto& admitted : guard_.Admit(m)) TakeSample(admitted);
}

// A message the time rule admitted (dds/stamp_guard.h).
void InverterNode::TakeSample(const dds::msg::GradiometerSample& m) {
  GradiometerSample s = dds::FromMsg(m);
  std::lock_guard<std::mutex> lk(mu_);
  DipoleFix fix;
  if (door_.Check(s) == SampleDefect::kNone) {
    if (const auto B0 = b0_->For(s)) {
      s.B -= *B0;
      fix = std::visit([&](auto& engine) { return engine.Process(s); }, engine_);
    } else {
      fix.sensor_id = s.sensor_id;
      fix.t_s = s.t_s;
      fix.reason = RejectReason::kNoRegionalField;
    }
  } else {
    // The engine rejects it by its own first gate (non_finite, zero_tensor)
    // without touching any state.
    fix = std::visit([&](auto& engine) { return engine.Process(s); }, engine_);
  }
  writer_->Write(ToMsg(fix, m.stamp_ns(), m.seq(), method_));
}

}  // namespace magnav::inversion
