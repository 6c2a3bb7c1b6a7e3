// FuzzDdsConvert: samples from the wire, through the generated type support,
// the conversions of dds/convert.h and the door of every service (entries.h).
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>

#include "entries.h"
#include "magnav/core/gradiometer.h"
#include "magnav/dds/convert.h"
#include "magnav/dds/repeat_filter.h"
#include "magnav/dds/sample_door.h"
#include "magnav/dds/topics.h"

namespace magnav::fuzz {
namespace {

namespace msg = magnav::msg;

// The CDR payload as Fast DDS hands it to the type support the services
// register (TopicTraits: CheckedPubSubType); false when it refuses it, and
// then the sample is the default one and the failure is marked for the
// reader's listener. It must never throw (that ended a service).
template <class M>
bool Deserialize(const std::uint8_t* data, std::size_t size, M* out) {
  typename dds::TopicTraits<M>::PubSubType type;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(static_cast<std::uint32_t>(size));
  if (size > 0) std::memcpy(payload.data, data, size);
  payload.length = static_cast<std::uint32_t>(size);
  const bool ok = type.deserialize(&payload, out);
  if (dds::internal::TakeDeserializeFailure() == ok) std::abort();
  if (!ok && !(*out == M())) std::abort();
  return ok;
}

// The CDR of a message (little endian), to compare messages bit for bit.
template <class M>
std::string Cdr(const M& m) {
  std::vector<char> buffer;
  return std::string(dds::SerializeCdr(m, &buffer));
}

// A payload of type M through the type support and, if accepted: the message
// through its record and back is the same message bit for bit (convert.h,
// every topic), then the repeat filter every consumer puts first (any key,
// seq and stamp: gaps, steps back, eviction) and `check`.
template <class M>
void Take(const std::uint8_t* data, std::size_t size, void (*check)(const M&) = nullptr) {
  static dds::RepeatFilter repeats(64, 8);  // small, so that eviction is reached
  M m;
  if (!Deserialize(data, size, &m)) return;
  if (Cdr(dds::ToMsg(dds::RecordOf(m))) != Cdr(m)) std::abort();
  const std::uint64_t missing = repeats.missing();
  const bool first = repeats.First(m);
  if (!first && repeats.missing() != missing) std::abort();  // a repeat never counts as a gap
  if (!first && repeats.First(m)) std::abort();              // nor becomes new
  if (check) check(m);
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void Gradiometer(const msg::GradiometerSample& m) {
  static dds::SampleDoor door("fuzz");
  const GradiometerSample s = dds::FromMsg(m);
  const SampleDefect defect = door.Check(s);
  if (defect != CheckSample(s)) std::abort();
  (void)SampleDefectName(defect);
  // Back to the wire and again: every value but the time survives bit for bit
  // (the time goes through whole nanoseconds).
  const GradiometerSample again = dds::FromMsg(dds::ToMsg(s, m.seq()));
  if (again.sensor_id != s.sensor_id || !SameBits(again.sigma_B, s.sigma_B) ||
      !SameBits(again.sigma_T, s.sigma_T)) {
    std::abort();
  }
  for (int i = 0; i < 3; ++i) {
    if (!SameBits(again.p_SinW[i], s.p_SinW[i]) || !SameBits(again.B[i], s.B[i])) std::abort();
    for (int j = 0; j < 3; ++j) {
      if (!SameBits(again.T(i, j), s.T(i, j))) std::abort();
    }
  }
  if (defect == SampleDefect::kNone && !std::isfinite(again.t_s)) std::abort();
}

void Magnetometer(const msg::MagnetometerSample& m) {
  for (const double reference_nT : {0.0, 48000.0}) {
    const double a = dds::AnomalyOf(m, reference_nT);
    // An anomaly sample carries it back (|B| = reference + anomaly, nT).
    if (std::isfinite(a) && std::abs(a) < 1e6) {
      const auto back = dds::AnomalySampleMsg(m.sensor_id(), m.stamp_ns(), m.seq(), a, reference_nT);
      const double b = dds::AnomalyOf(back, reference_nT);
      if (!(std::abs(b - a) <= 1e-6 * (std::abs(reference_nT) + std::abs(a) + 1.0))) std::abort();
    }
  }
}

void Nav(const msg::VesselNav& m) {
  const auto ins = dds::InsNavMsg(m.vessel_id(), m.stamp_ns(), m.geodetic()[0], m.geodetic()[1]);
  if (ins.source() != msg::NAV_INS || !SameBits(ins.geodetic()[0], m.geodetic()[0])) std::abort();
}

}  // namespace

void FuzzDdsConvert(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return;
  const std::uint8_t kind = data[0] % 7;
  ++data;
  --size;
  switch (kind) {
    case 0:
      return Take<msg::GradiometerSample>(data, size, Gradiometer);
    case 1:
      return Take<msg::MagnetometerSample>(data, size, Magnetometer);
    case 2:
      return Take<msg::VesselNav>(data, size, Nav);
    // The other topics a service reads: only through the type support and
    // the repeat filter.
    case 3:
      return Take<msg::DipoleFix>(data, size);
    case 4:
      return Take<msg::TrackEstimate>(data, size);
    case 5:
      return Take<msg::SensorPositionEstimate>(data, size);
    default:
      return Take<msg::MapFix>(data, size);
  }
}

}  // namespace magnav::fuzz
