// DDS adapter tests in the manner of Fast DDS's blackbox suite: a domain id
// derived from the process id, discovery awaited before sending, a peer in a
// separate process so samples really cross the loopback transports.
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <utime.h>
#include <unistd.h>

#include <bit>
#include <cstring>
#include <filesystem>
#include <map>
#include <thread>
#include <fstream>
#include <set>
#include <sstream>
#include <vector>

#include <gtest/gtest.h>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>

#include "magnav/dds/convert.h"
#include "magnav/dds/node.h"
#include "magnav/dds/repeat_filter.h"
#include "magnav/dds/shm_clean.h"
#include "magnav/dds/stamp_guard.h"
#include "raw_payload.h"
#include "sample_pattern.h"
#include "subprocess.h"
#include "test_data.h"

namespace magnav::dds {

namespace {

using namespace std::chrono_literals;

int TestDomain() { return testing::TestDomainId(); }

NodeOptions TestNode(const std::string& name) {
  NodeOptions o;
  o.name = name;
  o.domain_id = TestDomain();
  return o;
}

// The peer program in another process, on the test's domain.
class PeerProcess : public testing::Subprocess {
 public:
  PeerProcess(const std::string& mode, std::uint64_t n, int domain)
      : Subprocess({MAGNAV_DDS_PEER, mode, std::to_string(n)}, {{"MAGNAV_DOMAIN_ID", std::to_string(domain)}}) {}
};

bool BitEqual(const msg::GradiometerSample& a, const msg::GradiometerSample& b) {
  return a.sensor_id() == b.sensor_id() && a.stamp_ns() == b.stamp_ns() && a.seq() == b.seq() &&
         std::memcmp(a.sensor_position().data(), b.sensor_position().data(), 3 * sizeof(double)) == 0 &&
         std::memcmp(a.B().data(), b.B().data(), 3 * sizeof(double)) == 0 &&
         std::memcmp(a.T().data(), b.T().data(), 9 * sizeof(double)) == 0 &&
         std::bit_cast<std::uint64_t>(a.sigma_B()) == std::bit_cast<std::uint64_t>(b.sigma_B()) &&
         std::bit_cast<std::uint64_t>(a.sigma_T()) == std::bit_cast<std::uint64_t>(b.sigma_T());
}

TEST(Dds, TenThousandReliableSamplesAcrossProcessesNoneLostBitIdentical) {
  constexpr std::uint64_t kCount = 10000;
  const int domain = TestDomain();
  std::mutex mu;
  std::vector<char> seen(kCount, 0);
  std::uint64_t mismatches = 0, duplicates = 0, out_of_range = 0;
  {
    Node node(TestNode("dds_test_reader"));
    auto reader = node.CreateReader<msg::GradiometerSample>([&](const msg::GradiometerSample& s, const auto&) {
      std::lock_guard<std::mutex> lk(mu);
      if (s.seq() >= kCount) {
        ++out_of_range;
        return;
      }
      if (seen[s.seq()]) ++duplicates;
      seen[s.seq()] = 1;
      if (!BitEqual(s, testing::PatternSample(static_cast<std::uint32_t>(s.seq() % 4), s.seq()))) ++mismatches;
    });
    PeerProcess peer("stream", kCount, domain);
    ASSERT_TRUE(reader->WaitForSamples(kCount, 60s)) << "received " << reader->stats().samples.load();
    EXPECT_EQ(peer.Wait(30s), 0);
    EXPECT_EQ(peer.ReadLine(), "sent 10000");
    EXPECT_EQ(reader->stats().samples.load(), kCount);
    EXPECT_EQ(reader->stats().lost.load(), 0u);
    EXPECT_EQ(reader->stats().incompatible_qos.load(), 0u);
    // magnav's writers only: no companion reader, nothing received twice.
    EXPECT_FALSE(reader->has_companion());
    EXPECT_EQ(reader->stats().duplicates.load(), 0u);
  }
  std::lock_guard<std::mutex> lk(mu);
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<long>(kCount));
  EXPECT_EQ(mismatches, 0u);
  EXPECT_EQ(duplicates, 0u);
  EXPECT_EQ(out_of_range, 0u);
}

TEST(Dds, LateJoinerOfTransientLocalTopicGetsLastEstimate) {
  const int domain = TestDomain();
  PeerProcess peer("estimates", 5, domain);
  ASSERT_EQ(peer.ReadLine(), "ready");  // all 5 written before any reader exists
  std::mutex mu;
  std::vector<msg::DipoleFix> got;
  {
    Node node(TestNode("late_joiner"));
    auto reader = node.CreateReader<msg::DipoleFix>([&](const msg::DipoleFix& f, const auto&) {
      std::lock_guard<std::mutex> lk(mu);
      got.push_back(f);
    });
    ASSERT_TRUE(reader->WaitForSamples(5, 20s)) << "received " << reader->stats().samples.load();
  }
  std::lock_guard<std::mutex> lk(mu);
  ASSERT_EQ(got.size(), 5u);
  const msg::DipoleFix expected = testing::PatternFix(4);
  EXPECT_EQ(got.back().sample_seq(), 4u);
  EXPECT_EQ(got.back().position(), expected.position());
  EXPECT_EQ(got.back().condition_number(), expected.condition_number());
  EXPECT_EQ(std::string(got[1].reason().c_str()), "weak_signal");
  // SIGTERM: the peer deletes its entities and exits 0.
  peer.Signal(SIGTERM);
  EXPECT_EQ(peer.Wait(10s), 0);
}

// Every UDP socket the participant opens is bound to 127.0.0.1 (the loopback
// profile); no socket listens on a wildcard or multicast address.
TEST(Dds, LoopbackProfileBindsOnlyToLoopback) {
  Node node(TestNode("socket_probe"));
  auto w = node.CreateWriter<msg::GradiometerSample>();
  std::set<std::string> inodes;
  for (const auto& e : std::filesystem::directory_iterator("/proc/self/fd")) {
    std::error_code ec;
    const std::string target = std::filesystem::read_symlink(e.path(), ec).string();
    if (!ec && target.rfind("socket:[", 0) == 0) inodes.insert(target.substr(8, target.size() - 9));
  }
  int udp = 0;
  for (const char* table : {"/proc/net/udp", "/proc/net/udp6"}) {
    std::ifstream in(table);
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      std::istringstream ls(line);
      std::string sl, local, remote, st, queues, tr, retr, uid, timeout, inode;
      ls >> sl >> local >> remote >> st >> queues >> tr >> retr >> uid >> timeout >> inode;
      if (!inodes.count(inode)) continue;
      ++udp;
      const std::string addr = local.substr(0, local.find(':'));
      EXPECT_EQ(addr, "0100007F") << table << " socket bound to " << local;
    }
  }
  EXPECT_GT(udp, 0);
}

// Unicast discovery on loopback reaches the participant indices the initial
// peers cover (Fast DDS's default: 0–3). A field host runs more participants
// than that (the demo: 2 services, 3 recorders, replay); every one must find
// every other, including the 5th and 6th (indices 4 and 5 announce only to
// the indices in range, so with the default range they never meet).
TEST(Dds, EightParticipantsOnOneHostAllDiscoverEachOther) {
  constexpr int kNodes = 8;
  std::vector<std::unique_ptr<Node>> nodes;
  std::vector<std::unique_ptr<Writer<msg::GradiometerSample>>> writers;
  std::vector<std::unique_ptr<Reader<msg::GradiometerSample>>> readers;
  for (int i = 0; i < kNodes; ++i) {
    nodes.push_back(std::make_unique<Node>(TestNode("discovery_" + std::to_string(i))));
    writers.push_back(nodes.back()->CreateWriter<msg::GradiometerSample>());
    readers.push_back(nodes.back()->CreateReader<msg::GradiometerSample>([](const auto&, const auto&) {}));
  }
  for (int i = 0; i < kNodes; ++i) {
    EXPECT_TRUE(readers[i]->WaitForMatched(kNodes, 10s))
        << "participant " << i << " matched " << readers[i]->stats().matched.load() << " of " << kNodes << " writers";
  }
}

TEST(Dds, ConversionRoundTripsCoreSample) {
  GradiometerSample s;
  s.sensor_id = 3;
  s.t_s = 12.3;
  s.p_SinW = {1, 2, 3};
  s.B = {4e-5, 5e-6, 6e-7};
  s.T << 1e-9, 2e-9, 3e-9, 2e-9, 5e-9, 6e-9, 3e-9, 6e-9, -6e-9;
  s.sigma_B = 1e-9;
  s.sigma_T = 1.4e-9;
  const GradiometerSample r = FromMsg(ToMsg(s, 99));
  EXPECT_EQ(r.sensor_id, 3u);
  EXPECT_NEAR(r.t_s, 12.3, 1e-9);
  EXPECT_EQ(r.p_SinW, s.p_SinW);
  EXPECT_EQ(r.B, s.B);
  EXPECT_EQ(r.T, s.T);
  EXPECT_EQ(ToMsg(s, 99).seq(), 99u);
}

// Payloads that are not CDR of the type (found by fuzz/dds_entry.cc): the
// first byte of the encapsulation not 0 made the generated type support throw
// out of take_next_sample, which ended the process; a short one was handed
// over as a valid sample holding part of the previous one. Now both are
// skipped and counted, and the reader goes on.
TEST(Dds, BadPayloadsAreSkippedAndCounted) {
  std::mutex mu;
  std::vector<msg::GradiometerSample> received;
  Node reader_node(TestNode("dds_test_bad_payload_reader"));
  auto reader =
      reader_node.CreateReader<msg::GradiometerSample>([&](const msg::GradiometerSample& s, const auto&) {
        std::lock_guard<std::mutex> lk(mu);
        received.push_back(s);
      });
  Node writer_node(TestNode("dds_test_bad_payload_writer"));
  auto writer = writer_node.CreateWriter<RawPayload>();
  ASSERT_TRUE(writer->WaitForMatched(1, 10s));
  for (const RawPayload& p : testing::GoodBadBadGood()) ASSERT_TRUE(writer->Write(p));
  ASSERT_TRUE(reader->WaitForSamples(2, 10s)) << "received " << reader->stats().samples.load() << ", bad payloads "
                                              << reader->stats().bad_payloads.load();
  EXPECT_EQ(reader->stats().bad_payloads.load(), 2u);
  std::lock_guard<std::mutex> lk(mu);
  ASSERT_EQ(received.size(), 2u);
  for (const auto& s : received) EXPECT_TRUE(BitEqual(s, testing::GoodPayloadSample()));
}

// The same from another process: the reader's listener then runs in a Fast DDS
// receive thread, where the exception ended the process.
TEST(Dds, BadPayloadsFromAnotherProcessAreSkippedAndCounted) {
  std::mutex mu;
  std::vector<msg::GradiometerSample> received;
  Node node(TestNode("dds_test_bad_payload_reader"));
  auto reader = node.CreateReader<msg::GradiometerSample>([&](const msg::GradiometerSample& s, const auto&) {
    std::lock_guard<std::mutex> lk(mu);
    received.push_back(s);
  });
  PeerProcess peer("bad_payloads", 1, TestDomain());
  ASSERT_TRUE(reader->WaitForSamples(2, 30s)) << "received " << reader->stats().samples.load() << ", bad payloads "
                                              << reader->stats().bad_payloads.load();
  EXPECT_EQ(peer.Wait(30s), 0);
  EXPECT_EQ(peer.ReadLine(), "sent 4");
  EXPECT_EQ(reader->stats().bad_payloads.load(), 2u);
  std::lock_guard<std::mutex> lk(mu);
  ASSERT_EQ(received.size(), 2u);
  for (const auto& s : received) EXPECT_TRUE(BitEqual(s, testing::GoodPayloadSample()));
}

// Samples that reached a reader in one burst (a late joiner's history, the
// samples behind a repaired loss: one notification for all of them) are taken
// by one loop. Fast DDS refuses a bad payload inside take_next_sample and
// returns the good sample behind it from the same call; the listener took any
// refusal as "no sample" and dropped that good one (CI's TSan run of
// 2026-11-27 received one of BadPayloadsFromAnotherProcess's two). Here the
// four payloads wait in a reader without a listener, acknowledged, before the
// listener's loop (internal::TakeEach) takes them.
TEST(Dds, AGoodSampleBehindBadOnesInOneBurstIsTaken) {
  Node writer_node(TestNode("dds_test_burst_writer"));  // loads the profiles, too
  auto writer = writer_node.CreateWriter<RawPayload>();
  namespace f = eprosima::fastdds::dds;
  auto* factory = f::DomainParticipantFactory::get_instance();
  f::DomainParticipantQos pqos;
  ASSERT_EQ(factory->get_participant_qos_from_profile("magnav_loopback", pqos), ReturnCode_t::RETCODE_OK);
  f::DomainParticipant* participant = factory->create_participant(TestDomain(), pqos);
  ASSERT_NE(participant, nullptr);
  f::TypeSupport type(new TopicTraits<msg::GradiometerSample>::PubSubType());
  ASSERT_EQ(type.register_type(participant), ReturnCode_t::RETCODE_OK);
  f::Topic* topic = participant->create_topic(TopicTraits<msg::GradiometerSample>::kTopic, type.get_type_name(),
                                              f::TOPIC_QOS_DEFAULT);
  f::Subscriber* sub = participant->create_subscriber(f::SUBSCRIBER_QOS_DEFAULT);
  ASSERT_TRUE(topic && sub);
  f::DataReader* r = sub->create_datareader(topic, internal::ReaderQos(sub, "sensor_stream_reader"), nullptr);
  ASSERT_NE(r, nullptr);
  ASSERT_TRUE(writer->WaitForMatched(1, 10s));
  for (const RawPayload& p : testing::GoodBadBadGood()) ASSERT_TRUE(writer->Write(p));
  ASSERT_TRUE(writer->WaitForAcknowledgments(10s));
  msg::GradiometerSample sample;
  f::SampleInfo info;
  std::vector<msg::GradiometerSample> received;
  int refused = 0;
  internal::TakeEach(r, sample, info, [&](int n) { refused += n; }, [&] { received.push_back(sample); });
  EXPECT_EQ(refused, 2);
  ASSERT_EQ(received.size(), 2u);
  for (const auto& s : received) EXPECT_TRUE(BitEqual(s, testing::GoodPayloadSample()));
  participant->delete_contained_entities();
  factory->delete_participant(participant);
}

TEST(Dds, BadOptionsAndEnvironmentAreReported) {
  NodeOptions bad_domain = TestNode("bad");
  bad_domain.domain_id = 500;
  EXPECT_THROW(Node{bad_domain}, DdsError);
  NodeOptions bad_profile = TestNode("bad");
  bad_profile.participant_profile = "no_such_profile";
  EXPECT_THROW(Node{bad_profile}, DdsError);
  setenv("MAGNAV_DOMAIN_ID", "abc", 1);
  try {
    DomainIdFromEnvironment();
    ADD_FAILURE() << "no error";
  } catch (const DdsError& e) {
    EXPECT_NE(std::string(e.what()).find("MAGNAV_DOMAIN_ID='abc'"), std::string::npos);
  }
  setenv("MAGNAV_DOMAIN_ID", "17", 1);
  EXPECT_EQ(DomainIdFromEnvironment(), 17);
  unsetenv("MAGNAV_DOMAIN_ID");
  setenv("ROS_DOMAIN_ID", "9", 1);
  EXPECT_EQ(DomainIdFromEnvironment(), 9);
  unsetenv("ROS_DOMAIN_ID");
  EXPECT_EQ(DomainIdFromEnvironment(), 0);
}

// An extra profiles file (--dds-profiles, $MAGNAV_DDS_PROFILES) may redefine a
// built-in profile: it replaces the built-in one (was: "XMLPARSER Error:
// Error adding profile" and the built-in QoS stayed). Checked in a peer
// process (profiles load once per process): the sensor stream's history depth
// is the file's 7, not the built-in 1000.
TEST(Dds, ExtraProfilesFileOverridesABuiltInProfile) {
  const std::string dir = testing::TempDir();
  std::ofstream(dir + "/override.xml") << R"(<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <data_writer profile_name="sensor_stream_writer">
    <topic><historyQos><kind>KEEP_LAST</kind><depth>7</depth></historyQos></topic>
    <qos><reliability><kind>RELIABLE</kind></reliability><durability><kind>VOLATILE</kind></durability></qos>
  </data_writer>
</profiles>
)";
  const auto [rc, out] = testing::RunCommand({MAGNAV_DDS_PEER, "qos", "0"},
                                             {{"MAGNAV_DOMAIN_ID", std::to_string(TestDomain())},
                                              {"MAGNAV_DDS_PROFILES", dir + "/override.xml"}});
  ASSERT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("writer depth 7 reader depth 1000"), std::string::npos) << out;
  EXPECT_NE(out.find("profile 'sensor_stream_writer' from " + dir + "/override.xml replaces the built-in one"),
            std::string::npos)
      << out;
  const auto [rc0, out0] =
      testing::RunCommand({MAGNAV_DDS_PEER, "qos", "0"}, {{"MAGNAV_DOMAIN_ID", std::to_string(TestDomain())}});
  ASSERT_EQ(rc0, 0) << out0;
  EXPECT_NE(out0.find("writer depth 1000 reader depth 1000"), std::string::npos) << out0;
  // A broken file is refused, naming it.
  std::ofstream(dir + "/broken.xml") << "<profiles><data_writer profile_name=\"x\">";
  const auto [rc2, out2] = testing::RunCommand({MAGNAV_DDS_PEER, "qos", "0"},
                                               {{"MAGNAV_DOMAIN_ID", std::to_string(TestDomain())},
                                                {"MAGNAV_DDS_PROFILES", dir + "/broken.xml"}});
  EXPECT_NE(rc2, 0);
  EXPECT_NE(out2.find(dir + "/broken.xml"), std::string::npos) << out2;
}

TEST(Dds, ProfileFilterAndPolicyNames) {
  const std::string xml =
      "<profiles><data_writer profile_name=\"a\"><x/></data_writer>"
      "<data_reader profile_name=\"b\"><y/></data_reader><participant profile_name=\"c\"></participant></profiles>";
  EXPECT_EQ(internal::ProfileNames(xml), (std::set<std::string>{"a", "b", "c"}));
  EXPECT_EQ(internal::WithoutProfiles(xml, {"b"}),
            "<profiles><data_writer profile_name=\"a\"><x/></data_writer><participant profile_name=\"c\"></participant>"
            "</profiles>");
  EXPECT_EQ(internal::WithoutProfiles(xml, {"zz"}), xml);
  EXPECT_NE(std::string(internal::QosPolicyName(23)).find("data representation"), std::string::npos);
  EXPECT_STREQ(internal::QosPolicyName(2), "durability");
  EXPECT_STREQ(internal::QosPolicyName(11), "reliability");
}

// ROS 2 names (NodeOptions::ros2_names, $MAGNAV_ROS2_NAMES): the type name ROS 2's
// DDS layers use, and a bad value of the variable is an error naming it. The
// names on the wire are checked against Cyclone DDS by Interop.Cyclone_ros2_names.
TEST(Dds, Ros2Names) {
  EXPECT_EQ(internal::Ros2TypeName("magnav::msg::GradiometerSample"), "magnav::msg::dds_::GradiometerSample_");
  EXPECT_EQ(internal::Ros2TypeName("Plain"), "dds_::Plain_");
  setenv("MAGNAV_ROS2_NAMES", "yes", 1);
  try {
    Node node(TestNode("ros2"));
    ADD_FAILURE() << "no error";
  } catch (const DdsError& e) {
    EXPECT_NE(std::string(e.what()).find("MAGNAV_ROS2_NAMES='yes'"), std::string::npos) << e.what();
  }
  setenv("MAGNAV_ROS2_NAMES", "1", 1);
  Node node(TestNode("ros2"));
  auto w = node.CreateWriter<msg::GradiometerSample>();
  EXPECT_EQ(w->topic(), "rt/magnav/gradiometer");
  unsetenv("MAGNAV_ROS2_NAMES");
}

// A restarted producer's history: the same (key, seq, stamp) is a repeat; the
// same seq at a new time (a producer that started over) is not; memory is
// bounded per key.
TEST(Dds, RepeatFilterDropsExactRepeatsOnly) {
  RepeatFilter f(3);
  EXPECT_TRUE(f.First(MessageId{1, 10, 100}));
  EXPECT_TRUE(f.First(MessageId{2, 10, 100}));  // another sensor
  EXPECT_FALSE(f.First(MessageId{1, 10, 100}));
  EXPECT_TRUE(f.First(MessageId{1, 10, 200}));  // seq reused at a new time
  EXPECT_TRUE(f.First(MessageId{1, 11, 110}));
  EXPECT_TRUE(f.First(MessageId{1, 12, 120}));  // evicts (1, 10, 100): depth 3
  EXPECT_TRUE(f.First(MessageId{1, 10, 100}));
  EXPECT_EQ(f.repeats(), 1u);
  msg::DipoleFix fix = testing::PatternFix(4);
  EXPECT_TRUE(f.First(fix));
  EXPECT_FALSE(f.First(fix));
  // Bounded in keys: the least recently used key is forgotten.
  RepeatFilter g(8, 2);
  EXPECT_TRUE(g.First(MessageId{1, 0, 1}));
  EXPECT_TRUE(g.First(MessageId{2, 0, 1}));
  EXPECT_FALSE(g.First(MessageId{1, 0, 1}));  // key 1 used last
  EXPECT_TRUE(g.First(MessageId{3, 0, 1}));   // forgets key 2
  EXPECT_EQ(g.num_keys(), 2u);
  EXPECT_FALSE(g.First(MessageId{1, 0, 1}));
  EXPECT_TRUE(g.First(MessageId{2, 0, 1}));  // forgotten: taken as new
}

// Sequence gaps: numbers skipped are counted per key; a step back that is
// not a repeat (a producer that started over) is counted and followed;
// repeats and unsequenced messages never count.
TEST(Dds, RepeatFilterCountsSequenceGapsAndStepsBack) {
  RepeatFilter f;
  auto id = [](std::uint32_t key, std::uint64_t seq, std::uint64_t stamp) { return MessageId{key, seq, stamp, true}; };
  EXPECT_TRUE(f.First(id(1, 5, 50)));   // the first one sets where the key is
  EXPECT_TRUE(f.First(id(1, 6, 60)));
  EXPECT_TRUE(f.First(id(1, 10, 100)));  // 7, 8, 9 missing
  EXPECT_TRUE(f.First(id(2, 0, 100)));   // another key: its own count
  EXPECT_TRUE(f.First(id(2, 2, 120)));   // 1 missing
  EXPECT_EQ(f.missing(), 4u);
  EXPECT_FALSE(f.First(id(1, 6, 60)));  // a repeat: not a step back
  EXPECT_EQ(f.restarts(), 0u);
  EXPECT_TRUE(f.First(id(1, 0, 200)));  // started over
  EXPECT_TRUE(f.First(id(1, 1, 210)));  // followed: no gap
  EXPECT_EQ(f.restarts(), 1u);
  EXPECT_EQ(f.missing(), 4u);
  EXPECT_TRUE(f.First(MessageId{3, 0, 1}));  // unsequenced (estimates): seq 0 always
  EXPECT_TRUE(f.First(MessageId{3, 0, 2}));
  EXPECT_TRUE(f.First(MessageId{3, 7, 3}));
  EXPECT_EQ(f.missing(), 4u);
  EXPECT_EQ(f.restarts(), 1u);
  msg::GradiometerSample a = testing::PatternSample(4, 0), b = testing::PatternSample(4, 3);
  EXPECT_TRUE(f.First(a));
  EXPECT_TRUE(f.First(b));
  EXPECT_EQ(f.missing(), 6u);  // samples are sequenced
}

// Conflicting producers (issue 22 item 5): the same (key, seq, stamp) with
// another payload from another writer keeps the first and is counted; from
// the same writer it is a new message. A driver whose seq stays 0 is not
// followed; a wild seq jump is not counted as missing samples.
TEST(Dds, RepeatFilterKeepsTheFirstOfConflictingProducers) {
  RepeatFilter f;
  const MessageId id{1, 5, 50, true};
  EXPECT_TRUE(f.First(id, MessageOrigin{11, 100}));
  EXPECT_FALSE(f.First(id, MessageOrigin{22, 100}));  // a restarted producer's same message: a repeat
  EXPECT_EQ(f.repeats(), 1u);
  EXPECT_EQ(f.conflicts(), 0u);
  EXPECT_FALSE(f.First(id, MessageOrigin{22, 200}));  // another writer, another payload: conflict
  EXPECT_EQ(f.conflicts(), 1u);
  EXPECT_TRUE(f.First(id, MessageOrigin{11, 300}));  // the first writer's next message (coarse clock)
  EXPECT_EQ(f.repeats(), 1u);
  // Payload hashes of real messages: equal for equal messages only.
  msg::GradiometerSample a = testing::PatternSample(2, 7), b = a;
  EXPECT_EQ(PayloadHash(a), PayloadHash(b));
  b.B()[1] += 1e-12;
  EXPECT_NE(PayloadHash(a), PayloadHash(b));
  // A driver that leaves seq at 0: neither gaps nor restarts.
  RepeatFilter g;
  for (std::uint64_t k = 0; k < 50; ++k) EXPECT_TRUE(g.First(MessageId{3, 0, 1000 + k, true}, MessageOrigin{5, k}));
  EXPECT_EQ(g.missing(), 0u);
  EXPECT_EQ(g.restarts(), 0u);
  // A wild seq (10^18 on the wire): not 10^18 missing samples.
  RepeatFilter h;
  EXPECT_TRUE(h.First(MessageId{4, 1, 10, true}));
  EXPECT_TRUE(h.First(MessageId{4, 1000000000000000000ULL, 20, true}));
  EXPECT_EQ(h.missing(), 0u);
  EXPECT_EQ(h.wild_steps(), 1u);
}

// The wire's time rule (issue 25 item 1): a wild stamp or seq is held, then
// dropped when the stream goes on from before it, or handed on with the next
// message when that one confirms the stream really moved; 2^64-1 ns is
// refused outright. Before: a stamp of 2^64-1 gave an estimate at 1.8e10 s.
TEST(Dds, StampGuardHoldsWildStampsUntilTheNextSampleDecides) {
  StampGuard<msg::GradiometerSample> g("test: gradiometer sensor");
  auto sample = [](std::uint64_t seq, double t_s) {
    msg::GradiometerSample m = testing::PatternSample(1, seq);
    m.stamp_ns(static_cast<std::uint64_t>(t_s * 1e9));
    return m;
  };
  EXPECT_EQ(g.Admit(sample(0, 100.0)).size(), 1u);  // a stream's start
  EXPECT_EQ(g.Admit(sample(1, 100.1)).size(), 1u);
  EXPECT_TRUE(g.Admit(sample(2, 5e9)).empty());     // 158 years later: held
  EXPECT_EQ(g.Admit(sample(3, 100.3)).size(), 1u);  // the stream goes on: the suspect is dropped
  EXPECT_EQ(g.rejected(), 1u);
  EXPECT_TRUE(g.Admit(sample(1000000000000000000ULL, 100.4)).empty());  // seq 10^18: held
  EXPECT_EQ(g.Admit(sample(5, 100.5)).size(), 1u);
  EXPECT_EQ(g.rejected(), 2u);
  msg::GradiometerSample max = sample(6, 100.6);
  max.stamp_ns(~std::uint64_t{0});  // 2^64-1 ns: beyond 1e10 s, refused at once
  EXPECT_TRUE(g.Admit(max).empty());
  EXPECT_EQ(g.rejected(), 3u);
  // A real move (a clock set forward by a day): confirmed by the next sample.
  EXPECT_TRUE(g.Admit(sample(7, 86500.0)).empty());
  const auto both = g.Admit(sample(8, 86500.1));
  ASSERT_EQ(both.size(), 2u);
  EXPECT_EQ(both[0].seq(), 7u);
  EXPECT_EQ(both[1].seq(), 8u);
  EXPECT_EQ(g.jumps(), 1u);
  EXPECT_EQ(g.Admit(sample(9, 86500.2)).size(), 1u);
  EXPECT_EQ(g.rejected(), 3u);
}

// The reader pair's filter: a writer the profile's reader matches is served
// by it alone; a sample handed on once is never handed on again (by either
// reader), however the two interleave; history repair (numbers far below the
// newest) passes once; memory per writer is a fixed window.
TEST(Dds, DeliveryFilterHandsOnEachWriterSampleOnce) {
  using V = DeliveryFilter::Verdict;
  DeliveryFilter f;
  const WriterGuid ours{1}, stock{2};
  // Before the profile's reader matched `ours`, the companion hands on 100..110.
  for (std::uint64_t sn = 100; sn <= 110; ++sn) EXPECT_EQ(f.Offer(true, ours, sn), V::kDeliver);
  f.Matched(false, ours, +1);
  f.Matched(true, ours, +1);
  f.Matched(true, stock, +1);
  EXPECT_EQ(f.matched_writers(), 2);
  EXPECT_EQ(f.companion_only_writers(), 1);
  // Now the companion's copies of `ours` are dropped; the profile's reader
  // repairs the history 1..110 and goes on: 100..110 only once.
  EXPECT_EQ(f.Offer(true, ours, 111), V::kServedByProfileReader);
  int delivered = 0, duplicates = 0;
  for (std::uint64_t sn = 1; sn <= 120; ++sn) {
    const V v = f.Offer(false, ours, sn);
    delivered += v == V::kDeliver;
    duplicates += v == V::kDuplicate;
  }
  EXPECT_EQ(delivered, 109);  // 1..99 and 111..120
  EXPECT_EQ(duplicates, 11);
  // A stock writer: companion only, every number once.
  for (std::uint64_t sn = 1; sn <= 50; ++sn) EXPECT_EQ(f.Offer(true, stock, sn), V::kDeliver);
  EXPECT_EQ(f.Offer(true, stock, 25), V::kDuplicate);
  // Far below the window: history, passes once.
  EXPECT_EQ(f.Offer(true, stock, 1000000), V::kDeliver);
  EXPECT_EQ(f.Offer(true, stock, 3), V::kDeliver);
  f.Matched(true, stock, -1);
  EXPECT_EQ(f.matched_writers(), 1);
}

// Any writer's QoS (issue 22 item 1): writers with a stock driver's QoS —
// RELIABLE/VOLATILE (Cyclone DDS's default), BEST_EFFORT/VOLATILE (ROS 2's
// sensor data) — and magnav's own RELIABLE/TRANSIENT_LOCAL, all at once on
// one topic: a magnav reader hears every sample of each exactly once, and
// reports no incompatible QoS. Before, the stock writers were refused
// ("incompatible QoS: durability", "reliability").
TEST(Dds, WritersOfAnyQosAreHeardOnceEach) {
  namespace rtps = eprosima::fastrtps::rtps;
  constexpr std::uint64_t kPerWriter = 300;
  const int domain = TestDomain();
  std::mutex mu;
  std::map<std::pair<std::uint32_t, std::uint64_t>, int> seen;
  Node node(TestNode("dds_test_any_qos"));
  auto reader = node.CreateReader<msg::GradiometerSample>([&](const msg::GradiometerSample& s, const auto&) {
    std::lock_guard<std::mutex> lk(mu);
    ++seen[{s.sensor_id(), s.seq()}];
  });
  EXPECT_FALSE(reader->has_companion());  // made only when a writer needs it
  // A plain Fast DDS participant (no magnav code) with hand-made QoS.
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  fdds::DomainParticipant* pp = factory->create_participant_with_profile(domain, "magnav_loopback");
  ASSERT_NE(pp, nullptr);
  fdds::TypeSupport type(new msg::GradiometerSamplePubSubType());
  ASSERT_EQ(type.register_type(pp), eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK);
  fdds::Topic* topic = pp->create_topic("magnav/gradiometer", type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  fdds::Publisher* pub = pp->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  std::vector<fdds::DataWriter*> writers;
  for (int kind = 0; kind < 3; ++kind) {
    fdds::DataWriterQos q = fdds::DATAWRITER_QOS_DEFAULT;
    q.reliability().kind = kind == 1 ? fdds::BEST_EFFORT_RELIABILITY_QOS : fdds::RELIABLE_RELIABILITY_QOS;
    q.durability().kind = kind == 2 ? fdds::TRANSIENT_LOCAL_DURABILITY_QOS : fdds::VOLATILE_DURABILITY_QOS;
    q.history().kind = fdds::KEEP_ALL_HISTORY_QOS;
    writers.push_back(pub->create_datawriter(topic, q));
    ASSERT_NE(writers.back(), nullptr);
  }
  ASSERT_TRUE(reader->WaitForCompanion(20s));
  ASSERT_TRUE(reader->WaitForMatched(3, 20s));
  for (int kind = 0; kind < 3; ++kind) {
    fdds::PublicationMatchedStatus st;
    for (int k = 0; k < 200 && (writers[kind]->get_publication_matched_status(st), st.current_count) < 1; ++k) {
      std::this_thread::sleep_for(10ms);
    }
  }
  // Paced (a sensor's rate): a best-effort burst would test socket buffers.
  for (std::uint64_t i = 0; i < kPerWriter; ++i) {
    for (int kind = 0; kind < 3; ++kind) {
      msg::GradiometerSample m = testing::PatternSample(static_cast<std::uint32_t>(kind), i);
      ASSERT_TRUE(writers[kind]->write(&m));
    }
    if (i % 20 == 0) std::this_thread::sleep_for(1ms);
  }
  EXPECT_TRUE(reader->WaitForSamples(3 * kPerWriter, 20s)) << reader->stats().samples.load();
  std::this_thread::sleep_for(200ms);  // anything twice would come now
  pp->delete_contained_entities();
  factory->delete_participant(pp);
  std::lock_guard<std::mutex> lk(mu);
  EXPECT_EQ(seen.size(), 3 * kPerWriter);
  for (const auto& [key, n] : seen) EXPECT_EQ(n, 1) << "sensor " << key.first << " seq " << key.second;
  EXPECT_EQ(reader->stats().samples.load(), 3 * kPerWriter);
  EXPECT_EQ(reader->stats().incompatible_qos.load(), 0u);
  EXPECT_EQ(reader->stats().via_any_writer.load() >= 2 * kPerWriter, true) << reader->stats().via_any_writer.load();
}

// A tracker running for weeks: track ids are never reused, so the track
// writer sees ever new keys. Each ended track is unregistered; 300 tracks of
// 20 estimates each all go out (the profile allows 100 live keys at once).
// Without Unregister the writer refused every estimate after the 10th track
// (Fast DDS's default max_instances, before the profile set it): measured,
// 200 of 6000 written.
TEST(Dds, EndedKeysAreUnregisteredSoNewOnesAlwaysFit) {
  NodeOptions o;
  o.name = "dds_test_tracks";
  o.domain_id = testing::TestDomainId();
  Node node(o);
  auto w = node.CreateWriter<msg::TrackEstimate>();
  int refused = 0, unregister_refused = 0;
  for (std::uint32_t id = 1; id <= 300; ++id) {
    msg::TrackEstimate e;
    e.track_id(id);
    for (int k = 0; k < 20; ++k) {
      e.stamp_ns(1'000'000'000ull * id + 100'000'000ull * k);
      refused += w->Write(e) ? 0 : 1;
    }
    unregister_refused += w->Unregister(e) ? 0 : 1;
  }
  EXPECT_EQ(refused, 0);
  EXPECT_EQ(unregister_refused, 0);
  EXPECT_EQ(w->stats().samples.load(), 6000u);
}

// Stale shared-memory files: a segment whose lock file nobody holds (older
// than the grace period) goes with its lock; a held one and a young one stay;
// a dead port is reported, not removed (a live writer may still send to it:
// the Node waits out the lease first, then removes it).
TEST(Dds, StaleSharedMemoryOfDeadProcessesIsRemoved) {
  const std::filesystem::path dir = magnav::testing::TempDir();
  const auto make = [&](const std::string& name, bool old) {
    std::ofstream(dir / name) << "x";
    if (old) {
      struct utimbuf t {};
      t.actime = t.modtime = time(nullptr) - 3600;
      utime((dir / name).c_str(), &t);
    }
  };
  make("fastrtps_00000000000000aa", true);  // dead segment
  make("fastrtps_00000000000000aa_el", true);
  make("fastrtps_00000000000000bb", true);  // live segment: its lock is held
  make("fastrtps_00000000000000bb_el", true);
  make("fastrtps_00000000000000cc", false);  // just made: grace period
  make("fastrtps_00000000000000cc_el", false);
  make("fastrtps_port7411", true);  // a dead port: kept
  make("fastrtps_port7411_el", true);
  make("fastrtps_port7411_sl", true);
  make("sem.fastrtps_port7411_mutex", true);
  make("unrelated_file", true);
  const int held = open((dir / "fastrtps_00000000000000bb_el").c_str(), O_RDONLY);
  ASSERT_EQ(flock(held, LOCK_EX | LOCK_NB), 0);
  const ShmCleanResult r = CleanStaleSharedMemory(dir.string(), 2.0);
  close(held);
  EXPECT_EQ(r.segments, 1);
  EXPECT_EQ(r.in_use, 2);
  EXPECT_EQ(r.dead_ports, std::vector<std::string>{"fastrtps_port7411"});
  std::set<std::string> left;
  for (const auto& e : std::filesystem::directory_iterator(dir)) left.insert(e.path().filename().string());
  EXPECT_EQ(left, (std::set<std::string>{"fastrtps_00000000000000bb", "fastrtps_00000000000000bb_el",
                                         "fastrtps_00000000000000cc", "fastrtps_00000000000000cc_el",
                                         "fastrtps_port7411", "fastrtps_port7411_el", "fastrtps_port7411_sl",
                                         "sem.fastrtps_port7411_mutex", "unrelated_file"}));
  // The ports in the directory, alive or dead, and a participant index none
  // of them uses: domain 0, port 7411 = 7400 + 11 + 2·0 (index 0's data port).
  EXPECT_EQ(SharedMemoryPorts(dir.string()), std::vector<int>{7411});
  EXPECT_EQ(FreshParticipantId(0, SharedMemoryPorts(dir.string())), 1);
  EXPECT_EQ(FreshParticipantId(0, {7410, 7413, 7415}), 3);  // indices 0, 1, 2 taken
  EXPECT_EQ(FreshParticipantId(1, {7411}), 0);              // another domain's port
  EXPECT_EQ(FreshParticipantId(0, {7410, 7412}, 2), -1);    // none free below 2
  // The first process to see the dead port marks it (young); one that finds
  // the mark older than the lease may remove it (expired).
  DeadPortAges a = AgeDeadPorts(dir.string(), r.dead_ports, 4.0);
  EXPECT_EQ(a.marked_now, 1);
  EXPECT_EQ(a.young, std::vector<std::string>{"fastrtps_port7411"});
  EXPECT_TRUE(a.expired.empty());
  a = AgeDeadPorts(dir.string(), r.dead_ports, 4.0);
  EXPECT_EQ(a.marked_now, 0);
  EXPECT_EQ(a.young.size(), 1u);
  const auto old = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now()) - 10;
  struct utimbuf times {old, old};
  ASSERT_EQ(::utime((dir / "magnav_deadport_fastrtps_port7411").c_str(), &times), 0);
  a = AgeDeadPorts(dir.string(), r.dead_ports, 4.0);
  EXPECT_EQ(a.expired, std::vector<std::string>{"fastrtps_port7411"});
  // Removed with its locks, mutex and marker.
  RemoveDeadPorts(dir.string(), a.expired);
  EXPECT_FALSE(std::filesystem::exists(dir / "magnav_deadport_fastrtps_port7411"));
  EXPECT_FALSE(std::filesystem::exists(dir / "fastrtps_port7411"));
  EXPECT_FALSE(std::filesystem::exists(dir / "fastrtps_port7411_sl"));
  EXPECT_FALSE(std::filesystem::exists(dir / "sem.fastrtps_port7411_mutex"));
  EXPECT_TRUE(std::filesystem::exists(dir / "unrelated_file"));
}

}  // namespace
}  // namespace magnav::dds
