#include "mcap_topics.h"

#include <fastrtps/attributes/PublisherAttributes.h>
#include <fastrtps/xmlparser/XMLProfileManager.h>

#include <algorithm>

#include "embedded_idl.h"

namespace magnav::tools {

const std::vector<std::string>& AllTopics() {
  static const std::vector<std::string> t = {"gradiometer", "dipole_fix",      "track",  "magnetometer",
                                             "vessel_nav",  "sensor_position", "map_fix"};
  return t;
}

std::vector<std::string> TopicChoices() {
  std::vector<std::string> c = AllTopics();
  c.push_back("all");
  return c;
}

bool IsSensorTopic(const std::string& topic) {
  return topic == "gradiometer" || topic == "magnetometer" || topic == "vessel_nav";
}

std::string ShortTopic(const std::string& wire_topic) {
  std::string t = wire_topic;
  if (t.rfind("rt/", 0) == 0) t = t.substr(3);
  if (t.rfind("magnav/", 0) != 0) return "";
  t = t.substr(7);
  const auto& all = AllTopics();
  return std::find(all.begin(), all.end(), t) != all.end() ? t : "";
}

std::string TypeNameOf(const std::string& topic) {
  std::string name;
  WithTopicType(topic, [&](auto m) {
    typename dds::TopicTraits<decltype(m)>::PubSubType ts;
    name = ts.getName();
  });
  return name;
}

const char* MagnavIdl() { return kEmbeddedIdl; }

namespace {
const char* Reliability(eprosima::fastdds::dds::ReliabilityQosPolicyKind k) {
  return k == eprosima::fastdds::dds::RELIABLE_RELIABILITY_QOS ? "reliable" : "best_effort";
}
const char* Durability(eprosima::fastdds::dds::DurabilityQosPolicyKind k) {
  switch (k) {
    case eprosima::fastdds::dds::VOLATILE_DURABILITY_QOS:
      return "volatile";
    case eprosima::fastdds::dds::TRANSIENT_LOCAL_DURABILITY_QOS:
      return "transient_local";
    case eprosima::fastdds::dds::TRANSIENT_DURABILITY_QOS:
      return "transient";
    default:
      return "persistent";
  }
}
}  // namespace

mcap::KeyValues WriterQosMetadata(const std::string& topic) {
  std::string profile;
  WithTopicType(topic, [&](auto m) { profile = dds::TopicTraits<decltype(m)>::kWriterProfile; });
  mcap::KeyValues kv = {{"dds_writer_profile", profile}};
  eprosima::fastrtps::PublisherAttributes a;
  if (eprosima::fastrtps::xmlparser::XMLProfileManager::fillPublisherAttributes(profile, a, false) !=
      eprosima::fastrtps::xmlparser::XMLP_ret::XML_OK) {
    return kv;
  }
  kv.emplace_back("reliability", Reliability(a.qos.m_reliability.kind));
  kv.emplace_back("durability", Durability(a.qos.m_durability.kind));
  const bool keep_all = a.topic.historyQos.kind == eprosima::fastdds::dds::KEEP_ALL_HISTORY_QOS;
  kv.emplace_back("history", keep_all ? "keep_all" : "keep_last");
  if (!keep_all) kv.emplace_back("depth", std::to_string(a.topic.historyQos.depth));
  return kv;
}

}  // namespace magnav::tools
