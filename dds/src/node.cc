#include "magnav/dds/node.h"

#include <charconv>
#include <cstdlib>
#include <string_view>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <spdlog/spdlog.h>

#include "embedded_profiles.h"

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

int DomainIdFromEnvironment() {
  if (auto id = ParseDomain("MAGNAV_DOMAIN_ID")) return *id;
  if (auto id = ParseDomain("ROS_DOMAIN_ID")) return *id;
  return 0;
}

void LoadProfiles(const std::string& extra_file) {
  static std::once_flag once;
  static bool builtin_ok = false;
  std::call_once(once, [] {
    builtin_ok = fdds::DomainParticipantFactory::get_instance()->load_XML_profiles_string(
                     kEmbeddedProfiles, sizeof(kEmbeddedProfiles) - 1) == ReturnCode_t::RETCODE_OK;
  });
  if (!builtin_ok) throw DdsError("the built-in DDS profiles (config/magnav_profiles.xml) failed to load");
  if (!extra_file.empty()) {
    static std::mutex mu;
    std::lock_guard<std::mutex> lk(mu);
    if (fdds::DomainParticipantFactory::get_instance()->load_XML_profiles_file(extra_file) !=
        ReturnCode_t::RETCODE_OK) {
      throw DdsError(extra_file + ": Fast DDS could not load this XML profiles file (missing or invalid)");
    }
  }
}

Node::Node(const NodeOptions& options) {
  std::string err;
  if (!options.IsValid(&err)) throw DdsError("NodeOptions: " + err);
  LoadProfiles(options.profiles_file.empty() ? EnvOr("MAGNAV_DDS_PROFILES", "") : options.profiles_file);
  domain_id_ = options.domain_id ? *options.domain_id : DomainIdFromEnvironment();
  const std::string profile = options.participant_profile.empty()
                                  ? EnvOr("MAGNAV_DDS_PARTICIPANT", "magnav_loopback")
                                  : options.participant_profile;
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  fdds::DomainParticipantQos pqos;
  if (factory->get_participant_qos_from_profile(profile, pqos) != ReturnCode_t::RETCODE_OK) {
    throw DdsError("DDS participant profile '" + profile + "' not found in the loaded XML profiles");
  }
  pqos.name(options.name);
  participant_ = factory->create_participant(static_cast<fdds::DomainId_t>(domain_id_), pqos);
  if (!participant_) throw DdsError("cannot create a DDS participant on domain " + std::to_string(domain_id_));
  publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  subscriber_ = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (!publisher_ || !subscriber_) {
    participant_->delete_contained_entities();
    factory->delete_participant(participant_);
    throw DdsError("cannot create publisher/subscriber");
  }
  spdlog::debug("dds: participant '{}' on domain {} with profile '{}'", options.name, domain_id_, profile);
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

void LogIncompatible(const std::string& topic, const char* side, int policy_id) {
  spdlog::warn("dds: {} on '{}' has a peer with incompatible QoS (policy id {})", side, topic, policy_id);
}

void LogLost(const std::string& topic, int total, int change) {
  spdlog::warn("dds: reader on '{}' lost {} sample(s) ({} in total)", topic, change, total);
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
