// Raw bytes published under the gradiometer's type name: what a faulty or
// hostile peer could send. Shared by the DDS test and its peer process
// (Dds.BadPayloads*).
#pragma once

#include <cstdint>
#include <cstring>
#include <functional>
#include <vector>

#include <fastdds/dds/topic/TopicDataType.hpp>

#include "magnav/dds/topics.h"
#include "sample_pattern.h"

namespace magnav {
namespace dds {

struct RawPayload {
  std::vector<unsigned char> bytes;
};

class RawPayloadPubSubType : public eprosima::fastdds::dds::TopicDataType {
 public:
  RawPayloadPubSubType() {
    setName(msg::GradiometerSamplePubSubType().getName());
    m_typeSize = 1024;
    m_isGetKeyDefined = true;  // the gradiometer topic is keyed (sensor_id)
  }
  bool serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) override {
    const auto& b = static_cast<RawPayload*>(data)->bytes;
    if (b.size() > payload->max_size) return false;
    std::memcpy(payload->data, b.data(), b.size());
    payload->length = static_cast<std::uint32_t>(b.size());
    return true;
  }
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t*, void*) override { return false; }
  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override {
    return [data] { return static_cast<std::uint32_t>(static_cast<RawPayload*>(data)->bytes.size()); };
  }
  void* createData() override { return new RawPayload(); }
  void deleteData(void* data) override { delete static_cast<RawPayload*>(data); }
  bool getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t* handle, bool) override {
    *handle = eprosima::fastrtps::rtps::InstanceHandle_t();
    handle->value[15] = 1;  // one instance
    return true;
  }
};

template <>
struct TopicTraits<RawPayload> {
  using PubSubType = RawPayloadPubSubType;
  static constexpr const char* kTopic = TopicTraits<msg::GradiometerSample>::kTopic;
  static constexpr const char* kWriterProfile = TopicTraits<msg::GradiometerSample>::kWriterProfile;
  static constexpr const char* kReaderProfile = TopicTraits<msg::GradiometerSample>::kReaderProfile;
};

}  // namespace dds

namespace testing {

using dds::RawPayload;

inline dds::msg::GradiometerSample GoodPayloadSample() { return PatternSample(2, 7); }

// A good sample, one whose encapsulation is not CDR (its first byte not 0: as
// tests/data/fuzz/dds_convert/crash-727ee6b5-encapsulation-not-cdr), one cut
// short after 40 bytes, and the good one again.
inline std::vector<RawPayload> GoodBadBadGood() {
  dds::msg::GradiometerSample good = GoodPayloadSample();
  dds::msg::GradiometerSamplePubSubType type;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(type.m_typeSize);
  type.serialize(&good, &payload);
  RawPayload good_raw;
  good_raw.bytes.assign(payload.data, payload.data + payload.length);
  RawPayload not_cdr{{0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x17, 0, 0, 0, 0}};
  RawPayload truncated{{good_raw.bytes.begin(), good_raw.bytes.begin() + 40}};
  return {good_raw, not_cdr, truncated, good_raw};
}

}  // namespace testing
}  // namespace magnav
