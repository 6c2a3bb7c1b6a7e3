// Topic names, types and the QoS profile each uses (docs/PROTOCOL.md is the
// human-readable table of the same facts).
#pragma once

#include <exception>
#include <string_view>
#include <vector>

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>

#include "magnav/msg/magnav.h"
#include "magnav/msg/magnavPubSubTypes.h"

namespace magnav::dds {

namespace msg = ::magnav::msg;

namespace internal {

// Counts (per thread) the payloads CheckedPubSubType refused; the reader's
// listener takes the count right after take_next_sample (same thread). One
// take can refuse several: Fast DDS drops a payload that fails and goes on to
// the next change in the same call (TakeEach, node.h).
inline thread_local int deserialize_failures = 0;
inline int TakeDeserializeFailures() {
  const int n = deserialize_failures;
  deserialize_failures = 0;
  return n;
}
inline bool TakeDeserializeFailure() { return TakeDeserializeFailures() > 0; }

// The generated type support with a door on deserialisation. fastddsgen's
// deserialize() catches only a short buffer (NotEnoughMemoryException); a
// payload whose encapsulation header is not CDR (first byte not 0) throws
// BadParamException out of DataReader::take_next_sample, which ended the
// service (found by fuzz/dds_entry.cc). Here any failure returns false (Fast
// DDS 2.9.1 then drops the sample and takes the next one in the same call, or
// answers NO_DATA if there is none), resets the sample to its default and
// counts the failure for the reader's listener, which adds it to
// EndpointStats::bad_payloads and goes on taking.
template <class Generated, class M>
class CheckedPubSubType : public Generated {
 public:
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override {
    bool ok = false;
    try {
      ok = Generated::deserialize(payload, data);
    } catch (const std::exception&) {
      ok = false;
    }
    if (!ok) {
      *static_cast<M*>(data) = M();
      ++deserialize_failures;
    }
    return ok;
  }
};

}  // namespace internal

// TopicTraits<M>: default topic name, the generated TopicDataType and the XML
// endpoint profiles (config/magnav_profiles.xml) of message type M.
template <class M>
struct TopicTraits;

#define MAGNAV_TOPIC(Type, name, writer_profile, reader_profile) \
  template <>                                                    \
  struct TopicTraits<msg::Type> {                                \
    using PubSubType = internal::CheckedPubSubType<msg::Type##PubSubType, msg::Type>; \
    static constexpr const char* kTopic = name;                  \
    static constexpr const char* kWriterProfile = writer_profile; \
    static constexpr const char* kReaderProfile = reader_profile; \
  }

MAGNAV_TOPIC(GradiometerSample, "magnav/gradiometer", "sensor_stream_writer", "sensor_stream_reader");
MAGNAV_TOPIC(MagnetometerSample, "magnav/magnetometer", "sensor_stream_writer", "sensor_stream_reader");
MAGNAV_TOPIC(VesselNav, "magnav/vessel_nav", "sensor_stream_writer", "sensor_stream_reader");
MAGNAV_TOPIC(DipoleFix, "magnav/dipole_fix", "fix_stream_writer", "fix_stream_reader");
MAGNAV_TOPIC(TrackEstimate, "magnav/track", "track_stream_writer", "track_stream_reader");
MAGNAV_TOPIC(SensorPositionEstimate, "magnav/sensor_position", "estimate_writer", "estimate_reader");
MAGNAV_TOPIC(MapFix, "magnav/map_fix", "estimate_writer", "estimate_reader");

#undef MAGNAV_TOPIC

// The message's CDR serialisation (little-endian, DDS_CDR, as the type
// support writes it) into `buffer`, which is resized as needed and may be
// reused; the view is valid until `buffer` changes. One serialiser for the
// repeat filter's payload hash, the conversion tests and the fuzz targets.
template <class M>
std::string_view SerializeCdr(const M& m, std::vector<char>* buffer) {
  buffer->resize(M::getCdrSerializedSize(m) + 8);
  eprosima::fastcdr::FastBuffer fb(buffer->data(), buffer->size());
  eprosima::fastcdr::Cdr cdr(fb, eprosima::fastcdr::Cdr::LITTLE_ENDIANNESS, eprosima::fastcdr::Cdr::DDS_CDR);
  m.serialize(cdr);
  return std::string_view(buffer->data(), cdr.getSerializedDataLength());
}

}  // namespace magnav::dds
