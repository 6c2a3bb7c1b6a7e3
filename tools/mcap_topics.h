// magnav's topics in MCAP recordings: the one place where the MCAP library
// (tools/mcap, no DDS) meets the DDS types. A message is stored as the CDR
// its type support produces (what goes on the wire: the 4-byte encapsulation
// header, then the little-endian CDR body), with the type's IDL as schema
// (encoding omgidl) and the writer profile's QoS as channel metadata
// (docs/PROTOCOL.md, "Recordings (MCAP)").
#pragma once

#include <fastdds/rtps/common/SerializedPayload.h>

#include <cstdint>
#include <string>
#include <vector>

#include "magnav/dds/repeat_filter.h"
#include "magnav/dds/topics.h"
#include "magnav/mcap/mcap.h"

namespace magnav::tools {

// Topic names without "magnav/": gradiometer, dipole_fix, track, magnetometer,
// vessel_nav, sensor_position, map_fix.
const std::vector<std::string>& AllTopics();
// AllTopics() and "all": what --topic of record and replay accepts.
std::vector<std::string> TopicChoices();
// The sensor topics replay sends by default.
bool IsSensorTopic(const std::string& topic);
// "magnav/gradiometer" or "rt/magnav/gradiometer" -> "gradiometer"; "" for others.
std::string ShortTopic(const std::string& wire_topic);
// The DDS type name of a topic's messages ("magnav::msg::GradiometerSample").
std::string TypeNameOf(const std::string& topic);
// The IDL of every topic type (idl/magnav.idl, embedded at build time).
const char* MagnavIdl();
// Channel metadata: the QoS of the writer profile (after the built-in and
// extra profiles are loaded, i.e. after a Node exists) and its name.
mcap::KeyValues WriterQosMetadata(const std::string& topic);

// The type support's CDR of a message.
template <class M>
std::string ToCdr(const M& m) {
  typename dds::TopicTraits<M>::PubSubType ts;
  M copy = m;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(ts.getSerializedSizeProvider(&copy)());
  if (!ts.serialize(&copy, &payload)) throw std::runtime_error("cannot serialise a message");
  return std::string(reinterpret_cast<const char*>(payload.data), payload.length);
}

// A message from its CDR; false if the bytes are not CDR of the type.
template <class M>
bool FromCdr(const std::string& bytes, M* m) {
  typename dds::TopicTraits<M>::PubSubType ts;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(static_cast<std::uint32_t>(bytes.size()));
  std::copy(bytes.begin(), bytes.end(), payload.data);
  payload.length = static_cast<std::uint32_t>(bytes.size());
  if (bytes.size() < 4) return false;
  const bool ok = ts.deserialize(&payload, m);
  // CheckedPubSubType marks a failure for the DDS reader: cleared here.
  const bool failed = dds::internal::TakeDeserializeFailure();
  return ok && !failed;
}

// Calls f(M{}) with the message type of a topic (short name).
template <class F>
void WithTopicType(const std::string& topic, F&& f) {
  if (topic == "gradiometer") return f(dds::msg::GradiometerSample{});
  if (topic == "dipole_fix") return f(dds::msg::DipoleFix{});
  if (topic == "magnetometer") return f(dds::msg::MagnetometerSample{});
  if (topic == "vessel_nav") return f(dds::msg::VesselNav{});
  if (topic == "sensor_position") return f(dds::msg::SensorPositionEstimate{});
  if (topic == "map_fix") return f(dds::msg::MapFix{});
  if (topic == "track") return f(dds::msg::TrackEstimate{});
  throw std::runtime_error("unknown topic " + topic);
}

// The key (sensor, vessel, track or vehicle id) and per-key sequence number
// of a message (seq: gradiometer, magnetometer; sample_seq: dipole_fix;
// others have none: -1), as the repeat filter reads them (dds::IdOf).
template <class M>
std::uint32_t KeyOf(const M& m) {
  return dds::IdOf(m).key;
}
template <class M>
std::int64_t SeqOf(const M& m) {
  const dds::MessageId id = dds::IdOf(m);
  return id.sequenced ? static_cast<std::int64_t>(id.seq) : -1;
}
inline void ShiftSeq(dds::msg::GradiometerSample& m, std::uint64_t d) { m.seq(m.seq() + d); }
inline void ShiftSeq(dds::msg::MagnetometerSample& m, std::uint64_t d) { m.seq(m.seq() + d); }
inline void ShiftSeq(dds::msg::DipoleFix& m, std::uint64_t d) { m.sample_seq(m.sample_seq() + d); }
template <class M>
void ShiftSeq(M&, std::uint64_t) {}

}  // namespace magnav::tools
