// The message conversions of dds/convert.h (layer 1: every topic type <->
// its record, exactly) and of dds/convert_<lib>.h (layer 2: what each
// library's types become on the wire). Pure values: no participant, no
// network; runs in milliseconds.
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>

#include "magnav/core/units.h"
#include "magnav/dds/convert.h"
#include "magnav/dds/convert_inversion.h"
#include "magnav/dds/convert_localizer.h"
#include "magnav/dds/convert_mapmatch.h"
#include "magnav/dds/convert_tracker.h"

namespace magnav::dds {
namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();

// The message's CDR serialisation: equal bytes = equal messages, NaN fields
// and appended fields included (operator== of the generated types says NaN
// != NaN).
template <class M>
std::vector<char> Bytes(const M& m) {
  std::vector<char> buffer;
  const std::string_view bytes = SerializeCdr(m, &buffer);
  return std::vector<char>(bytes.begin(), bytes.end());
}

// message -> record -> message gives the same bytes, and so does record ->
// message -> record -> message.
template <class M>
void ExpectRoundTrip(const M& m) {
  const auto r = RecordOf(m);
  const M back = ToMsg(r);
  EXPECT_EQ(Bytes(back), Bytes(m));
  EXPECT_EQ(Bytes(ToMsg(RecordOf(back))), Bytes(m));
}

// Distinct values for every field (no two alike, none the default).
struct Filler {
  double k = 0.0;
  double D() { return (k += 1.0) * 1.25e-3 + 1.0 / 3.0; }
  template <std::size_t N>
  std::array<double, N> A() {
    std::array<double, N> a{};
    for (auto& x : a) x = D();
    return a;
  }
};

// Stamps and seqs past 2^53: a double would round them.
constexpr std::uint64_t kStamp = (std::uint64_t{1} << 62) + 12345;
constexpr std::uint64_t kSeq = (std::uint64_t{1} << 60) + 7;

msg::GradiometerSample Gradiometer(Filler& f) {
  msg::GradiometerSample m;
  m.sensor_id(0xfffffff1u);
  m.stamp_ns(kStamp);
  m.seq(kSeq);
  m.sensor_position(f.A<3>());
  m.B(f.A<3>());
  m.T(f.A<9>());
  m.sigma_B(f.D());
  m.sigma_T(f.D());
  return m;
}

msg::MagnetometerSample Magnetometer(Filler& f) {
  msg::MagnetometerSample m;
  m.sensor_id(42);
  m.stamp_ns(kStamp);
  m.seq(kSeq);
  m.sensor_position(f.A<3>());
  m.B(f.A<3>());
  m.sigma_B(f.D());
  return m;
}

msg::VesselNav Nav(Filler& f, msg::NavSource source) {
  msg::VesselNav m;
  m.vessel_id(7);
  m.stamp_ns(kStamp);
  m.source(source);
  m.position(f.A<3>());
  m.velocity(f.A<3>());
  m.heading(f.D());
  m.sigma_position(f.A<3>());
  m.sigma_velocity(f.D());
  m.sigma_heading(f.D());
  m.geodetic(f.A<3>());
  return m;
}

msg::DipoleFix Fix(Filler& f, msg::FixMethod method) {
  msg::DipoleFix m;
  m.sensor_id(9);
  m.stamp_ns(kStamp);
  m.sample_seq(kSeq);
  m.method(method);
  m.valid(true);
  m.reason(std::string(64, 'r'));  // the longest the wire holds
  m.position(f.A<3>());
  m.has_moment(true);
  m.moment(f.A<3>());
  m.condition_number(f.D());
  m.covariance(f.A<9>());
  return m;
}

msg::TrackEstimate Track(Filler& f) {
  msg::TrackEstimate m;
  m.track_id(123456);
  m.stamp_ns(kStamp);
  m.position(f.A<3>());
  m.velocity(f.A<3>());
  m.heading(f.D());
  m.turn_rate(f.D());
  m.covariance(f.A<9>());
  m.moment_body(f.A<3>());
  m.moment_covariance(f.A<9>());
  m.num_sensors(5);
  m.usable(true);
  m.state(msg::TRACK_STATE_COASTING);
  return m;
}

msg::SensorPositionEstimate SensorPosition(Filler& f) {
  msg::SensorPositionEstimate m;
  m.sensor_id(11);
  m.stamp_ns(kStamp);
  m.position(f.A<3>());
  m.covariance(f.A<9>());
  m.crlb(f.A<9>());
  return m;
}

msg::MapFix MapFixMsg(Filler& f, msg::FixMethod method, msg::MapFixStatus status) {
  msg::MapFix m;
  m.vehicle_id(3);
  m.stamp_ns(kStamp);
  m.method(method);
  m.method_name(std::string(32, 'm'));  // the longest the wire holds
  m.lat_deg(f.D());
  m.lon_deg(f.D());
  m.score(f.D());
  m.covariance(f.A<4>());
  m.status(status);
  return m;
}

TEST(DdsConvert, EveryTopicRoundTripsExactly) {
  Filler f;
  ExpectRoundTrip(Gradiometer(f));
  ExpectRoundTrip(Magnetometer(f));
  ExpectRoundTrip(Nav(f, msg::NAV_GNSS));
  ExpectRoundTrip(Fix(f, msg::METHOD_TED));
  ExpectRoundTrip(Track(f));
  ExpectRoundTrip(SensorPosition(f));
  ExpectRoundTrip(MapFixMsg(f, msg::METHOD_PF, msg::MAP_FIX_STATUS_OK));
  // Defaults (all zero, empty strings) too.
  ExpectRoundTrip(msg::GradiometerSample());
  ExpectRoundTrip(msg::MagnetometerSample());
  ExpectRoundTrip(msg::VesselNav());
  ExpectRoundTrip(msg::DipoleFix());
  ExpectRoundTrip(msg::TrackEstimate());
  ExpectRoundTrip(msg::SensorPositionEstimate());
  ExpectRoundTrip(msg::MapFix());
}

TEST(DdsConvert, RecordsHoldEachFieldWhereTheIdlSays) {
  Filler f;
  const msg::TrackEstimate t = Track(f);
  const TrackRecord r = RecordOf(t);
  EXPECT_EQ(r.stamp_ns, kStamp);
  EXPECT_EQ(r.p_VinW_m.z(), t.position()[2]);
  EXPECT_EQ(r.cov_p_m2(0, 1), t.covariance()[1]);  // row-major: [3 i + j] = (i, j)
  EXPECT_EQ(r.cov_p_m2(1, 0), t.covariance()[3]);
  EXPECT_EQ(r.cov_m_B(2, 1), t.moment_covariance()[7]);
  EXPECT_EQ(r.state, TrackState::kCoasting);
  const msg::MapFix mf = MapFixMsg(f, msg::METHOD_AFPF, msg::MAP_FIX_STATUS_LOST);
  const MapFixRecord mr = RecordOf(mf);
  EXPECT_EQ(mr.cov_ne_m2(0, 1), mf.covariance()[1]);
  EXPECT_EQ(mr.cov_ne_m2(1, 0), mf.covariance()[2]);
  EXPECT_EQ(mr.status, MapFixStatus::kLost);
  EXPECT_EQ(mr.method, FixMethod::kAfpf);
  EXPECT_EQ(mr.method_name, std::string(32, 'm'));
  const msg::GradiometerSample g = Gradiometer(f);
  EXPECT_EQ(RecordOf(g).T_Tpm(1, 2), g.T()[5]);
  EXPECT_EQ(RecordOf(g).seq, kSeq);
  EXPECT_EQ(RecordOf(Fix(f, msg::METHOD_EGT)).reason, std::string(64, 'r'));
}

TEST(DdsConvert, EveryEnumValueRoundTripsAndUnknownOnesAreCarried) {
  Filler f;
  // Every named value, and one past the last (a newer writer's appended value).
  for (std::uint32_t v = 0; v <= msg::METHOD_AFPF + 1; ++v) {
    const auto method = static_cast<msg::FixMethod>(v);
    ExpectRoundTrip(Fix(f, method));
    ExpectRoundTrip(MapFixMsg(f, method, msg::MAP_FIX_STATUS_OK));
    EXPECT_EQ(static_cast<std::uint32_t>(RecordOf(Fix(f, method)).method), v);
  }
  for (std::uint32_t v = 0; v <= msg::MAP_FIX_STATUS_CONVERGING + 1; ++v) {
    const auto status = static_cast<msg::MapFixStatus>(v);
    const msg::MapFix m = MapFixMsg(f, msg::METHOD_PF, status);
    ExpectRoundTrip(m);
    EXPECT_EQ(static_cast<std::uint32_t>(RecordOf(m).status), v);
    EXPECT_EQ(ToMsg(RecordOf(m)).status(), status);
  }
  for (std::uint32_t v = 0; v <= msg::TRACK_STATE_COASTING + 1; ++v) {
    msg::TrackEstimate m = Track(f);
    m.state(static_cast<msg::TrackState>(v));
    ExpectRoundTrip(m);
    EXPECT_EQ(static_cast<std::uint32_t>(RecordOf(m).state), v);
    EXPECT_EQ(ToMsg(RecordOf(m)).state(), m.state());
  }
  for (std::uint32_t v = 0; v <= msg::NAV_OTHER + 1; ++v) {
    const auto source = static_cast<msg::NavSource>(v);
    ExpectRoundTrip(Nav(f, source));
    EXPECT_EQ(static_cast<std::uint32_t>(RecordOf(Nav(f, source)).source), v);
  }
  EXPECT_EQ(RecordOf(Nav(f, msg::NAV_INS)).source, NavSource::kIns);
  EXPECT_EQ(RecordOf(MapFixMsg(f, msg::METHOD_PF, msg::MAP_FIX_STATUS_OFF_MAP)).status, MapFixStatus::kOffMap);
}

TEST(DdsConvert, NonFiniteValuesAreCarriedUnchanged) {
  Filler f;
  msg::VesselNav n = Nav(f, msg::NAV_INS);
  n.position({kNaN, -std::numeric_limits<double>::infinity(), 1e308});
  n.heading(kNaN);
  ExpectRoundTrip(n);
  msg::DipoleFix d = Fix(f, msg::METHOD_MC);
  d.covariance()[4] = kNaN;
  d.condition_number(std::numeric_limits<double>::infinity());
  ExpectRoundTrip(d);
  EXPECT_TRUE(std::isnan(RecordOf(d).cov_p_m2(1, 1)));
  // The map-matching helpers build through the records too.
  ExpectRoundTrip(InsNavMsg(2, kStamp, 45.1, 10.2));
  ExpectRoundTrip(AnomalySampleMsg(2, kStamp, kSeq, 12.5, 48000.0));
  EXPECT_NEAR(AnomalyOf(AnomalySampleMsg(2, kStamp, kSeq, 12.5, 48000.0), 48000.0), 12.5, 1e-6);
  EXPECT_EQ(InsNavMsg(2, kStamp, 45.1, 10.2).source(), msg::NAV_INS);
}

// Layer 2: the libraries' types.
TEST(DdsConvert, InversionFixOnTheWire) {
  inversion::DipoleFix fix;
  fix.sensor_id = 4;
  fix.valid = false;
  fix.reason = inversion::RejectReason::kWeakSignal;
  fix.p_DinW = {1, 2, 3};
  fix.has_moment = true;
  fix.m_W = {kNaN, 0, 0};  // not finite: no moment on the wire
  fix.cond = 17.0;
  const msg::DipoleFix m = ToMsg(fix, kStamp, kSeq, FixMethodOf(inversion::Method::kTedEgt));
  EXPECT_EQ(m.method(), msg::METHOD_TED_EGT);
  EXPECT_EQ(m.reason().to_string(), "weak_signal");
  EXPECT_FALSE(m.has_moment());
  EXPECT_EQ(m.moment(), (std::array<double, 3>{0, 0, 0}));
  EXPECT_EQ(m.covariance(), (std::array<double, 9>{}));  // NaN covariance: all 0 = unknown
  EXPECT_EQ(m.sample_seq(), kSeq);
  EXPECT_EQ(FixMethodOf(inversion::Method::kTed), FixMethod::kTed);
  EXPECT_EQ(FixMethodOf(inversion::Method::kEgt), FixMethod::kEgt);
  // The tracker reads it back: time, sensor, position, valid.
  const tracker::DipoleFix back = FromMsg(m);
  EXPECT_EQ(back.sensor_id, 4u);
  EXPECT_EQ(back.p_DinW, fix.p_DinW);
  EXPECT_FALSE(back.valid);
  EXPECT_DOUBLE_EQ(back.t_s, NanosToSeconds(kStamp));
}

TEST(DdsConvert, TrackerEpochOnTheWire) {
  tracker::EpochEstimate e;
  e.t_s = 12.5;
  e.p_VinW = {1, 2, 3};
  e.speed_mps = 2.0;
  e.heading_rad = 0.5;
  e.turn_rate_radps = 0.01;
  e.num_samples = 6;
  e.usable = true;
  e.has_covariance = true;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) e.cov_state(i, j) = 10 * i + j + 1;
  const msg::TrackEstimate m =
      ToMsg(e, Eigen::Vector3d(1, 2, 3), Eigen::Matrix3d::Identity(), 77, tracker::TrackState::kConfirmed);
  EXPECT_EQ(m.track_id(), 77u);
  EXPECT_EQ(m.stamp_ns(), SecondsToNanos(12.5));
  EXPECT_EQ(m.covariance()[5], e.cov_state(1, 2));
  EXPECT_EQ(m.num_sensors(), 6u);
  EXPECT_NEAR(std::hypot(m.velocity()[0], m.velocity()[1]), 2.0, 1e-12);
  EXPECT_EQ(m.state(), msg::TRACK_STATE_CONFIRMED);
  EXPECT_EQ(ToMsg(e, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero(), 77, tracker::TrackState::kCoasting).state(),
            msg::TRACK_STATE_COASTING);
  e.usable = false;  // an unusable estimate: no covariance
  EXPECT_EQ(ToMsg(e, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero(), 77, tracker::TrackState::kConfirmed).covariance(),
            (std::array<double, 9>{}));
}

TEST(DdsConvert, LocalizerTypesOnTheWire) {
  localizer::MagSample s;
  s.t_s = 3.25;
  s.sensor_id = 8;
  s.B_T = {1e-8, -2e-8, 3e-8};
  const msg::MagnetometerSample ms = ToMsg(s, 5, 1e-9);
  EXPECT_EQ(ms.seq(), 5u);
  EXPECT_TRUE(std::isnan(ms.sensor_position()[0]));
  const localizer::MagSample s2 = FromMsg(ms);
  EXPECT_EQ(s2.sensor_id, 8u);
  EXPECT_EQ(s2.B_T, s.B_T);
  EXPECT_DOUBLE_EQ(s2.t_s, 3.25);
  localizer::GnssFix g;
  g.t_s = 4.5;
  g.p_xy_m = {100, -50};
  g.sigma_m = 2.5;
  const msg::VesselNav n = ToMsg(g, 0, 1.5);
  EXPECT_EQ(n.source(), msg::NAV_GNSS);
  EXPECT_EQ(n.position()[2], 1.5);
  const localizer::GnssFix g2 = FromMsg(n);
  EXPECT_EQ(g2.p_xy_m, g.p_xy_m);
  EXPECT_EQ(g2.sigma_m, 2.5);
  msg::VesselNav wider = n;
  wider.sigma_position({1.0, 4.0, 0.0});
  EXPECT_EQ(FromMsg(wider).sigma_m, 4.0);  // the larger horizontal σ
  localizer::SensorEstimate e;
  e.sensor_id = 2;
  e.p_SinW_m = {5, 6, 30};
  e.cov_xy_m2 << 1, 2, 3, 4;
  e.crlb_joint_m2 << 5, 6, 7, 8;
  const msg::SensorPositionEstimate pe = ToMsg(e, 9.0);
  EXPECT_EQ(pe.covariance(), (std::array<double, 9>{1, 2, 0, 3, 4, 0, 0, 0, 0}));  // z known: 0
  EXPECT_EQ(pe.crlb(), (std::array<double, 9>{5, 6, 0, 7, 8, 0, 0, 0, 0}));
  EXPECT_EQ(pe.stamp_ns(), SecondsToNanos(9.0));
}

TEST(DdsConvert, MatcherStepOnTheWire) {
  mapmatch::StepDiagnostics d;
  d.lat_deg = 45.0;
  d.lon_deg = 10.0;
  d.ess = 321.0;
  const msg::MapFix ok = ToMsg(d, mapmatch::ParticleFilterKind::kPf, 1, kStamp);
  EXPECT_EQ(ok.method(), msg::METHOD_PF);
  EXPECT_EQ(ok.method_name().to_string(), "pf");
  EXPECT_EQ(ok.status(), msg::MAP_FIX_STATUS_OK);
  EXPECT_EQ(ok.score(), 321.0);
  d.update = mapmatch::StepUpdate::kAllOffMap;
  EXPECT_EQ(ToMsg(d, mapmatch::ParticleFilterKind::kAfpf, 1, kStamp).status(), msg::MAP_FIX_STATUS_OFF_MAP);
  EXPECT_EQ(ToMsg(d, mapmatch::ParticleFilterKind::kAfpf, 1, kStamp).method(), msg::METHOD_AFPF);
  d.lost = true;  // lost outranks off the map
  EXPECT_EQ(ToMsg(d, mapmatch::ParticleFilterKind::kAfpf, 1, kStamp).status(), msg::MAP_FIX_STATUS_LOST);
  d.partly_observable = true;  // and partly observable
  EXPECT_EQ(ToMsg(d, mapmatch::ParticleFilterKind::kAfpf, 1, kStamp).status(), msg::MAP_FIX_STATUS_LOST);
  d.lost = false;  // off the map outranks partly observable
  EXPECT_EQ(ToMsg(d, mapmatch::ParticleFilterKind::kAfpf, 1, kStamp).status(), msg::MAP_FIX_STATUS_OFF_MAP);
  d.update = mapmatch::StepUpdate::kUpdated;
  EXPECT_EQ(ToMsg(d, mapmatch::ParticleFilterKind::kAfpf, 1, kStamp).status(), msg::MAP_FIX_STATUS_PARTLY_OBSERVABLE);
  d.converging = true;  // partly observable outranks converging (appended, issue 25: it takes only what was ok)
  EXPECT_EQ(ToMsg(d, mapmatch::ParticleFilterKind::kAfpf, 1, kStamp).status(), msg::MAP_FIX_STATUS_PARTLY_OBSERVABLE);
  d.partly_observable = false;
  EXPECT_EQ(ToMsg(d, mapmatch::ParticleFilterKind::kAfpf, 1, kStamp).status(), msg::MAP_FIX_STATUS_CONVERGING);
  EXPECT_EQ(RecordOf(ToMsg(d, mapmatch::ParticleFilterKind::kPf, 1, kStamp)).status, MapFixStatus::kConverging);
  d.update = mapmatch::StepUpdate::kAllOffMap;  // off the map outranks converging
  EXPECT_EQ(ToMsg(d, mapmatch::ParticleFilterKind::kAfpf, 1, kStamp).status(), msg::MAP_FIX_STATUS_OFF_MAP);
  d.lost = true;  // and lost outranks both
  EXPECT_EQ(ToMsg(d, mapmatch::ParticleFilterKind::kAfpf, 1, kStamp).status(), msg::MAP_FIX_STATUS_LOST);
}

}  // namespace
}  // namespace magnav::dds
