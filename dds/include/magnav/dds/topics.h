// Topic names, types and the QoS profile each uses (docs/PROTOCOL.md is the
// human-readable table of the same facts).
#pragma once

#include "magnav/msg/magnav.h"
#include "magnav/msg/magnavPubSubTypes.h"

namespace magnav::dds {

namespace msg = ::magnav::msg;

// TopicTraits<M>: default topic name, the generated TopicDataType and the XML
// endpoint profiles (config/magnav_profiles.xml) of message type M.
template <class M>
struct TopicTraits;

#define MAGNAV_TOPIC(Type, name, writer_profile, reader_profile) \
  template <>                                                    \
  struct TopicTraits<msg::Type> {                                \
    using PubSubType = msg::Type##PubSubType;                    \
    static constexpr const char* kTopic = name;                  \
    static constexpr const char* kWriterProfile = writer_profile; \
    static constexpr const char* kReaderProfile = reader_profile; \
  }

MAGNAV_TOPIC(GradiometerSample, "magnav/gradiometer", "sensor_stream_writer", "sensor_stream_reader");
MAGNAV_TOPIC(MagnetometerSample, "magnav/magnetometer", "sensor_stream_writer", "sensor_stream_reader");
MAGNAV_TOPIC(VesselNav, "magnav/vessel_nav", "sensor_stream_writer", "sensor_stream_reader");
MAGNAV_TOPIC(DipoleFix, "magnav/dipole_fix", "fix_stream_writer", "fix_stream_reader");
MAGNAV_TOPIC(TrackEstimate, "magnav/track", "estimate_writer", "estimate_reader");
MAGNAV_TOPIC(SensorPositionEstimate, "magnav/sensor_position", "estimate_writer", "estimate_reader");
MAGNAV_TOPIC(MapFix, "magnav/map_fix", "estimate_writer", "estimate_reader");

#undef MAGNAV_TOPIC

}  // namespace magnav::dds
