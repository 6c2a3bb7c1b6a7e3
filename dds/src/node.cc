#include "magnav/dds/node.h"

#include <algorithm>
#include <charconv>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <set>
#include <string_view>
#include <thread>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <spdlog/spdlog.h>

#include "embedded_profiles.h"
#include "magnav/dds/shm_clean.h"

namespace magnav::dds {

using eprosima::fastrtps::types::ReturnCode_t;

namespace {
constexpr int kMaxDomainId = 232;  // RTPS port mapping limit with default port parameters

std::optional<int> ParseDomain(const char* var) {
  const char* v = std::getenv(var);
  if (!v || !*v) return std::nullopt;
  int id = -1;
  const std::string_view s(v);
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), id);
  if (ec != std::errc() || p != s.data() + s.size() || id < 0 || id > kMaxDomainId) {
    throw DdsError(std::string("$") + var + "='" + v + "' is not a domain id in 0.." + std::to_string(kMaxDomainId));
  }
  return id;
}

std::string EnvOr(const char* var, const std::string& fallback) {
  const char* v = std::getenv(var);
  return (v && *v) ? std::string(v) : fallback;
}
}  // namespace

bool NodeOptions::IsValid(std::string* error) const {
  if (domain_id && (*domain_id < 0 || *domain_id > kMaxDomainId)) {
    if (error) *error = "domain_id must be in 0.." + std::to_string(kMaxDomainId);
    return false;
  }
  if (name.empty()) {
    if (error) *error = "name must not be empty";
    return false;
  }
  return true;
}

bool Ros2NamesFromEnvironment() {
  const char* v = std::getenv("MAGNAV_ROS2_NAMES");
  if (!v || !*v || std::string_view(v) == "0") return false;
  if (std::string_view(v) == "1") return true;
  throw DdsError(std::string("$MAGNAV_ROS2_NAMES='") + v + "' must be 1 (ROS 2 names) or 0");
}

int DomainIdFromEnvironment() {
  if (auto id = ParseDomain("MAGNAV_DOMAIN_ID")) return *id;
  if (auto id = ParseDomain("ROS_DOMAIN_ID")) return *id;
  return 0;
}

namespace internal {

std::string Ros2TypeName(const std::string& type_name) {
  const std::size_t last = type_name.rfind("::");
  if (last == std::string::npos) return "dds_::" + type_name + "_";
  return type_name.substr(0, last) + "::dds_::" + type_name.substr(last + 2) + "_";
}

std::set<std::string> ProfileNames(const std::string& xml) {
  std::set<std::string> names;
  static const std::string kAttr = "profile_name=\"";
  for (std::size_t at = xml.find(kAttr); at != std::string::npos; at = xml.find(kAttr, at + 1)) {
    const std::size_t begin = at + kAttr.size(), end = xml.find('"', begin);
    if (end != std::string::npos) names.insert(xml.substr(begin, end - begin));
  }
  return names;
}

std::string WithoutProfiles(std::string xml, const std::set<std::string>& names) {
  for (const std::string& name : names) {
    const std::size_t attr = xml.find("profile_name=\"" + name + "\"");
    if (attr == std::string::npos) continue;
    const std::size_t open = xml.rfind('<', attr);
    const std::size_t tag_end = xml.find_first_of(" \t\r\n>", open + 1);
    if (open == std::string::npos || tag_end == std::string::npos) continue;
    const std::string closing = "</" + xml.substr(open + 1, tag_end - open - 1) + ">";
    const std::size_t close = xml.find(closing, attr);
    if (close == std::string::npos) continue;
    xml.erase(open, close + closing.size() - open);
  }
  return xml;
}

}  // namespace internal

void LoadProfiles(const std::string& extra_file) {
  // The built-in profiles are loaded once per process, after the first extra
  // file: a profile of the extra file with a built-in name replaces the
  // built-in one (Fast DDS refuses a name loaded twice, so the built-in copy
  // is left out). An extra file given to a later node may only add profiles.
  static std::mutex mu;
  static bool builtin_loaded = false;
  static std::set<std::string> loaded_files;
  std::lock_guard<std::mutex> lk(mu);
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  std::set<std::string> overrides;
  if (!extra_file.empty() && loaded_files.insert(extra_file).second) {
    std::ifstream in(extra_file);
    if (!in) throw DdsError(extra_file + ": cannot open this XML profiles file");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::set<std::string> builtin = internal::ProfileNames(kEmbeddedProfiles);
    for (const std::string& name : internal::ProfileNames(text)) {
      if (!builtin.count(name)) continue;
      if (builtin_loaded) {
        throw DdsError(extra_file + ": profile '" + name +
                       "' is a built-in one, already in use in this process; give the file to the first node "
                       "(--dds-profiles or $MAGNAV_DDS_PROFILES) to override it");
      }
      overrides.insert(name);
    }
    if (factory->load_XML_profiles_file(extra_file) != ReturnCode_t::RETCODE_OK) {
      throw DdsError(extra_file + ": Fast DDS could not load this XML profiles file (invalid XML, or a profile name "
                                  "given twice)");
    }
    for (const std::string& name : overrides) {
      spdlog::info("dds: profile '{}' from {} replaces the built-in one", name, extra_file);
    }
  }
  if (!builtin_loaded) {
    const std::string builtin = internal::WithoutProfiles(kEmbeddedProfiles, overrides);
    if (factory->load_XML_profiles_string(builtin.c_str(), builtin.size()) != ReturnCode_t::RETCODE_OK) {
      throw DdsError("the built-in DDS profiles (config/magnav_profiles.xml) failed to load");
    }
    builtin_loaded = true;
  }
}

Node::Node(const NodeOptions& options) {
  std::string err;
  if (!options.IsValid(&err)) throw DdsError("NodeOptions: " + err);
  // Shared-memory files of processes that died without cleaning up (kill -9),
  // once per process, before this participant makes its own.
  static std::once_flag shm_cleaned;
  static bool dead_ports_found = false;
  std::call_once(shm_cleaned, [] {
    const ShmCleanResult c = CleanStaleSharedMemory();
    if (c.segments > 0) spdlog::info("dds: removed {} shared-memory segment(s) left by dead processes", c.segments);
    if (!c.dead_ports.empty()) {
      // See shm_clean.h: taking a dead process's port number again can leave
      // this participant deaf (a Fast DDS 2.9 shared-memory bug). Its ports
      // go once the peers have forgotten it.
      const DeadPortAges a = AgeDeadPorts("/dev/shm", c.dead_ports, kZombiePortWaitS);
      RemoveDeadPorts("/dev/shm", a.expired);
      if (!a.young.empty()) {
        dead_ports_found = true;
        if (a.marked_now > 0) {
          spdlog::info("dds: {} shared-memory port(s) of a process that died (e.g. {}): joining with a participant "
                       "index they do not use; they are removed {} s from now",
                       a.young.size(), a.young.front(), kZombiePortWaitS);
          std::thread([ports = a.young] {
            std::this_thread::sleep_for(std::chrono::duration<double>(kZombiePortWaitS));
            RemoveDeadPorts("/dev/shm", ports);
          }).detach();
        }
      }
    }
  });
  LoadProfiles(options.profiles_file.empty() ? EnvOr("MAGNAV_DDS_PROFILES", "") : options.profiles_file);
  domain_id_ = options.domain_id ? *options.domain_id : DomainIdFromEnvironment();
  ros2_names_ = options.ros2_names ? *options.ros2_names : Ros2NamesFromEnvironment();
  any_writer_ = options.any_writer;
  const std::string profile = options.participant_profile.empty()
                                  ? EnvOr("MAGNAV_DDS_PARTICIPANT", "magnav_loopback")
                                  : options.participant_profile;
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  fdds::DomainParticipantQos pqos;
  if (factory->get_participant_qos_from_profile(profile, pqos) != ReturnCode_t::RETCODE_OK) {
    throw DdsError("DDS participant profile '" + profile + "' not found in the loaded XML profiles");
  }
  pqos.name(options.name);
  if (dead_ports_found && pqos.wire_protocol().participant_id < 0) {
    pqos.wire_protocol().participant_id = FreshParticipantId(domain_id_, SharedMemoryPorts());
  }
  participant_ = factory->create_participant(static_cast<fdds::DomainId_t>(domain_id_), pqos);
  if (!participant_ && pqos.wire_protocol().participant_id >= 0 && dead_ports_found) {
    pqos.wire_protocol().participant_id = -1;  // that index was taken after all (a UDP-only peer): Fast DDS's choice
    participant_ = factory->create_participant(static_cast<fdds::DomainId_t>(domain_id_), pqos);
  }
  if (!participant_) throw DdsError("cannot create a DDS participant on domain " + std::to_string(domain_id_));
  publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  subscriber_ = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (!publisher_ || !subscriber_) {
    participant_->delete_contained_entities();
    factory->delete_participant(participant_);
    throw DdsError("cannot create publisher/subscriber");
  }
  spdlog::debug("dds: participant '{}' on domain {} with profile '{}'{}", options.name, domain_id_, profile,
                ros2_names_ ? ", ROS 2 names" : "");
}

Node::~Node() {
  if (!participant_) return;
  participant_->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
}

fdds::Topic* Node::GetTopic(const std::string& name, const std::string& type) {
  std::lock_guard<std::mutex> lk(topics_mu_);
  if (fdds::TopicDescription* d = participant_->lookup_topicdescription(name)) {
    auto* t = dynamic_cast<fdds::Topic*>(d);
    if (!t || t->get_type_name() != type) {
      throw DdsError("topic '" + name + "' already exists with type " + d->get_type_name());
    }
    return t;
  }
  fdds::Topic* t = participant_->create_topic(name, type, fdds::TOPIC_QOS_DEFAULT);
  if (!t) throw DdsError("cannot create topic '" + name + "' of type " + type);
  return t;
}

namespace internal {

fdds::DataWriterQos WriterQos(fdds::Publisher* pub, const std::string& profile) {
  fdds::DataWriterQos q;
  if (pub->get_datawriter_qos_from_profile(profile, q) != ReturnCode_t::RETCODE_OK) {
    throw DdsError("data_writer profile '" + profile + "' not found in the loaded XML profiles");
  }
  return q;
}

fdds::DataReaderQos ReaderQos(fdds::Subscriber* sub, const std::string& profile) {
  fdds::DataReaderQos q;
  if (sub->get_datareader_qos_from_profile(profile, q) != ReturnCode_t::RETCODE_OK) {
    throw DdsError("data_reader profile '" + profile + "' not found in the loaded XML profiles");
  }
  return q;
}

std::optional<fdds::DataReaderQos> AnyWriterQos(const fdds::DataReaderQos& q) {
  if (q.reliability().kind == fdds::BEST_EFFORT_RELIABILITY_QOS &&
      q.durability().kind == fdds::VOLATILE_DURABILITY_QOS) {
    return std::nullopt;
  }
  fdds::DataReaderQos any = q;
  any.reliability().kind = fdds::BEST_EFFORT_RELIABILITY_QOS;
  any.durability().kind = fdds::VOLATILE_DURABILITY_QOS;
  return any;
}

WriterGuid GuidOf(const eprosima::fastrtps::rtps::GUID_t& guid) {
  WriterGuid g{};
  std::copy(std::begin(guid.guidPrefix.value), std::end(guid.guidPrefix.value), g.begin());
  std::copy(std::begin(guid.entityId.value), std::end(guid.entityId.value), g.begin() + 12);
  return g;
}

WriterGuid GuidOf(const eprosima::fastrtps::rtps::InstanceHandle_t& handle) {
  return GuidOf(eprosima::fastrtps::rtps::iHandle2GUID(handle));
}

const char* QosPolicyName(int policy_id) {
  using P = fdds::QosPolicyId_t;
  switch (static_cast<P>(policy_id)) {
    case P::DURABILITY_QOS_POLICY_ID:
      return "durability";
    case P::PRESENTATION_QOS_POLICY_ID:
      return "presentation";
    case P::DEADLINE_QOS_POLICY_ID:
      return "deadline";
    case P::LATENCYBUDGET_QOS_POLICY_ID:
      return "latency budget";
    case P::OWNERSHIP_QOS_POLICY_ID:
      return "ownership";
    case P::LIVELINESS_QOS_POLICY_ID:
      return "liveliness";
    case P::RELIABILITY_QOS_POLICY_ID:
      return "reliability";
    case P::DESTINATIONORDER_QOS_POLICY_ID:
      return "destination order";
    case P::DATAREPRESENTATION_QOS_POLICY_ID:
      return "data representation (magnav writes XCDR1; an XCDR2-only peer matches nothing)";
    case P::TYPECONSISTENCYENFORCEMENT_QOS_POLICY_ID:
      return "type consistency enforcement";
    case P::DISABLEPOSITIVEACKS_QOS_POLICY_ID:
      return "disable positive acks";
    default:
      return "unnamed";
  }
}

void LogIncompatible(const std::string& topic, const char* side, int policy_id) {
  // Fast DDS's policy ids; other vendors number them differently (Cyclone
  // DDS reports data representation as 25), so the name is what counts.
  spdlog::warn("dds: {} on '{}' has a peer with incompatible QoS: policy {} (Fast DDS policy id {}); "
               "see docs/PROTOCOL.md for magnav's QoS",
               side, topic, QosPolicyName(policy_id), policy_id);
}

void LogLost(const std::string& topic, int total, int change) {
  spdlog::warn("dds: reader on '{}' lost {} sample(s) ({} in total)", topic, change, total);
}

void LogFlowTimeout(const std::string& topic, std::chrono::milliseconds timeout) {
  spdlog::warn("dds: writer on '{}': a reader did not acknowledge within {} s (too slow, or gone and not yet "
               "forgotten); going on without it (it may miss samples)",
               topic, static_cast<double>(timeout.count()) / 1000.0);
}

void LogBadPayload(const std::string& topic) {
  spdlog::error(
      "dds: a sample on '{}' is not a valid payload of its type (skipped; EndpointStats::bad_payloads "
      "counts them, logged once)",
      topic);
}

void LogCompanion(const std::string& topic, bool made) {
  if (made) {
    spdlog::info("dds: a writer on '{}' is volatile or best-effort: its samples are taken by a best-effort, volatile "
                 "companion reader (docs/PROTOCOL.md, \"Any writer's QoS\")",
                 topic);
  } else {
    spdlog::error("dds: cannot create the best-effort companion reader on '{}': volatile or best-effort writers "
                  "are not heard",
                  topic);
  }
}

void LogCallbackError(const std::string& topic, const char* what) {
  spdlog::error("dds: handler of a sample on '{}' failed: {} (sample skipped)", topic, what);
}

bool WaitUntil(std::mutex& mu, std::condition_variable& cv, const std::function<bool()>& pred,
               std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lk(mu);
  return cv.wait_for(lk, timeout, pred);
}

}  // namespace internal
}  // namespace magnav::dds
