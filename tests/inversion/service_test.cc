// magnav-inverter as a process on loopback DDS: every sample gets a DipoleFix
// (bad ones rejected with the gate's reason), the fixes are exactly what the
// library computes, and the service survives bad input and stops cleanly.
#include <signal.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <mutex>

#include <gtest/gtest.h>

#include "magnav/core/gradiometer.h"
#include "magnav/dds/convert.h"
#include "magnav/dds/node.h"
#include "magnav/inversion/inverter.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::inversion {
namespace {

using namespace std::chrono_literals;
namespace msg = ::magnav::msg;

// Publishes samples to the magnav-inverter running on `domain` and returns the
// fixes it publishes, in order (the service answers every sample).
std::vector<msg::DipoleFix> Exchange(int domain, const std::vector<GradiometerSample>& samples) {
  std::mutex mu;
  std::vector<msg::DipoleFix> fixes;
  dds::NodeOptions o;
  o.name = "inverter_service_test";
  o.domain_id = domain;
  dds::Node node(o);
  auto reader = node.CreateReader<msg::DipoleFix>([&](const msg::DipoleFix& f, const auto&) {
    std::lock_guard<std::mutex> lk(mu);
    fixes.push_back(f);
  });
  auto writer = node.CreateWriter<msg::GradiometerSample>();
  EXPECT_TRUE(writer->WaitForMatched(1, 20s));
  EXPECT_TRUE(reader->WaitForMatched(1, 20s));
  for (std::size_t i = 0; i < samples.size(); ++i) EXPECT_TRUE(writer->Write(dds::ToMsg(samples[i], i)));
  EXPECT_TRUE(reader->WaitForSamples(samples.size(), 20s)) << reader->stats().samples.load();
  reader.reset();
  std::lock_guard<std::mutex> lk(mu);
  return fixes;
}

TEST(InverterService, FixForEverySampleBadOnesRejectedServiceSurvives) {
  const int domain = testing::TestDomainId();
  const GradiometerFile file = ReadGradiometerFile(testing::ReferencePath("track_pass_auv_1sensor_squid.csv"));
  // Samples around the closest approach (t = 70..80 s), then bad ones, then good ones again.
  std::vector<GradiometerSample> good;
  for (const auto& s : file.samples) {
    if (s.t_s >= 70.0 && s.t_s < 80.0) good.push_back(s);
  }
  ASSERT_EQ(good.size(), 100u);
  std::vector<GradiometerSample> input(good.begin(), good.begin() + 50);
  GradiometerSample bad = good[49];
  const double nan = std::numeric_limits<double>::quiet_NaN();
  bad.T(0, 1) = nan;
  input.push_back(bad);  // non_finite
  bad = good[49];
  bad.T.setZero();
  input.push_back(bad);  // zero_tensor
  bad = good[49];
  bad.T(0, 1) += 0.5 * bad.T.norm();
  input.push_back(bad);  // asymmetric
  bad = good[49];
  bad.p_SinW.x() = nan;
  input.push_back(bad);  // non_finite
  input.insert(input.end(), good.begin() + 50, good.end());
  for (std::size_t i = 50; i < 54; ++i) input[i].t_s = good[49].t_s + 0.01 * static_cast<double>(i - 49);

  testing::Subprocess service({MAGNAV_SERVICE_BIN, "--b0", "2e-05,1e-06,4.5e-05", "--stats-period", "0"},
                              {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}});
  const std::vector<msg::DipoleFix> fixes = Exchange(domain, input);
  service.Signal(SIGTERM);
  EXPECT_EQ(service.Wait(10s), 0) << "the service must stop cleanly after bad input";

  // The same samples through the library, in the same order.
  InverterOptions options;
  options.B0_W = *file.B0;
  Inverter inverter(options);
  ASSERT_EQ(fixes.size(), input.size());
  const std::vector<std::string> bad_reasons = {"non_finite", "zero_tensor", "asymmetric", "non_finite"};
  int valid = 0;
  for (std::size_t i = 0; i < input.size(); ++i) {
    // Round trip through the message (time stamps in ns) as the service saw it.
    const DipoleFix want = inverter.Process(dds::FromMsg(dds::ToMsg(input[i], i)));
    const msg::DipoleFix& got = fixes[i];
    ASSERT_EQ(got.sample_seq(), i);
    EXPECT_EQ(got.valid(), want.valid) << i;
    EXPECT_EQ(std::string(got.reason().c_str()), RejectReasonName(want.reason)) << i;
    EXPECT_EQ(got.method(), msg::METHOD_TED_EGT);
    if (i >= 50 && i < 54) {
      EXPECT_FALSE(got.valid());
      EXPECT_EQ(std::string(got.reason().c_str()), bad_reasons[i - 50]);
    }
    if (want.valid) {
      ++valid;
      for (int k = 0; k < 3; ++k) EXPECT_EQ(got.position()[k], want.p_DinW[k]) << i;
    }
  }
  EXPECT_GT(valid, 40);  // most samples near the closest approach pass the gates
}

// Options from a TOML file: method and weak-signal gate taken from the file.
TEST(InverterService, ReadsOptionsFromAConfigFile) {
  const int domain = testing::TestDomainId();
  const std::string cfg = testing::TempDir() + "/inverter.toml";
  std::ofstream(cfg) << "# magnav-inverter options\nmethod = \"ted\"\nmin-snr = 1e12\nb0 = \"2e-05,1e-06,4.5e-05\"\n";
  testing::Subprocess service({MAGNAV_SERVICE_BIN, "--config", cfg, "--stats-period", "0"},
                              {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}});
  const GradiometerFile file = ReadGradiometerFile(testing::ReferencePath("track_pass_auv_1sensor_squid.csv"));
  const std::vector<msg::DipoleFix> fixes = Exchange(domain, {file.samples[750]});  // t = 75 s, strongest signal
  service.Signal(SIGTERM);
  EXPECT_EQ(service.Wait(10s), 0);
  ASSERT_EQ(fixes.size(), 1u);
  EXPECT_EQ(fixes[0].method(), msg::METHOD_TED);
  EXPECT_FALSE(fixes[0].valid());
  EXPECT_EQ(std::string(fixes[0].reason().c_str()), "weak_signal");  // SNR ~1e6 < 1e12

  // A bad value in the file is an error naming the option, exit code != 0.
  std::ofstream(cfg) << "max-speed = fast\n";
  const auto [rc, out] = testing::RunCommand({MAGNAV_SERVICE_BIN, "--config", cfg});
  EXPECT_NE(rc, 0);
  EXPECT_NE(out.find("max-speed"), std::string::npos) << out;
}

}  // namespace
}  // namespace magnav::inversion
