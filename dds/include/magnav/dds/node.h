// The one thin DDS adapter of magnav: a Node owns a DomainParticipant with
// one Publisher and one Subscriber, registers types and topics once, and hands
// out typed writers and readers whose QoS comes from XML profiles
// (config/magnav_profiles.xml, compiled in). Incompatible QoS and lost samples
// are logged and counted. Destroying the Node (after its writers/readers)
// deletes every entity, so nothing is left in /dev/shm.
//
// Domain id: NodeOptions::domain_id if set, else $MAGNAV_DOMAIN_ID, else
// $ROS_DOMAIN_ID, else 0. Participant profile: NodeOptions, else
// $MAGNAV_DDS_PARTICIPANT, else "magnav_loopback" (UDP on 127.0.0.1 + shared
// memory only). Extra XML profiles: NodeOptions::profiles_file, else
// $MAGNAV_DDS_PROFILES. Names on the wire: magnav's ("magnav/gradiometer",
// "magnav::msg::GradiometerSample"), or ROS 2's with NodeOptions::ros2_names /
// $MAGNAV_ROS2_NAMES=1.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <set>
#include <string>
#include <thread>
#include <utility>

#include <fastdds/dds/core/status/StatusMask.hpp>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "magnav/dds/delivery_filter.h"
#include "magnav/dds/topics.h"

namespace magnav::dds {

namespace fdds = eprosima::fastdds::dds;

class DdsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct NodeOptions {
  std::string name = "magnav";           // participant name (shows in discovery tools)
  std::optional<int> domain_id;          // 0..232; unset = from the environment
  std::string participant_profile;       // "" = $MAGNAV_DDS_PARTICIPANT or "magnav_loopback"
  std::string profiles_file;             // extra XML profiles; "" = $MAGNAV_DDS_PROFILES or none
  // ROS 2 names on the wire: topic "rt/<name>", type "<module>::msg::dds_::<Type>_" (what ROS 2's
  // DDS layers use), so ROS 2 tools and nodes with the same message layout see magnav's topics.
  // Unset = $MAGNAV_ROS2_NAMES ("1" on, "0" or unset off). docs/INTEROP.md.
  std::optional<bool> ros2_names;
  // Readers also match writers of any reliability and durability (a
  // BEST_EFFORT/VOLATILE companion beside the profile's reader, see Reader).
  // Off: only writers compatible with the reader profile match (benchmarks
  // measure the companion's cost this way).
  bool any_writer = true;

  bool IsValid(std::string* error) const;
};

// Domain id from the environment: $MAGNAV_DOMAIN_ID, else $ROS_DOMAIN_ID,
// else 0. Throws DdsError naming the variable if it is not an integer in 0..232.
int DomainIdFromEnvironment();

// Loads the built-in profiles (once per process) and then `extra_file` if
// non-empty. Throws DdsError naming the file if Fast DDS rejects it.
void LoadProfiles(const std::string& extra_file);

// Counters shared by writers and readers.
struct EndpointStats {
  std::atomic<std::uint64_t> samples{0};        // written / received
  std::atomic<std::uint64_t> lost{0};           // reported lost by the middleware
  std::atomic<std::uint64_t> incompatible_qos{0};
  std::atomic<std::uint64_t> callback_errors{0};  // reader callbacks that threw
  std::atomic<std::uint64_t> bad_payloads{0};     // received payloads that are not CDR of the type (skipped)
  std::atomic<int> matched{0};                  // currently matched peers
  std::atomic<std::uint64_t> flow_timeouts{0};  // writer flow control: readers not acknowledging in time
  // Readers with an any-writer companion (Reader): samples dropped because
  // the other DataReader had handed on the same (writer GUID, RTPS seq)
  // already, and samples handed on from writers only the companion matched.
  std::atomic<std::uint64_t> duplicates{0};
  std::atomic<std::uint64_t> via_any_writer{0};
};

namespace internal {
// Non-template parts, in node.cc.
fdds::DataWriterQos WriterQos(fdds::Publisher* pub, const std::string& profile);
fdds::DataReaderQos ReaderQos(fdds::Subscriber* sub, const std::string& profile);
void LogIncompatible(const std::string& topic, const char* side, int policy_id);
// Logged once per reader: a payload its type support could not deserialise.
void LogBadPayload(const std::string& topic);
// The name of a Fast DDS QoS policy id, for logs ("unnamed" for others).
const char* QosPolicyName(int policy_id);
// Profile names an XML profiles text defines, and the text without the
// elements of the given profiles (how an extra file overrides built-ins).
std::set<std::string> ProfileNames(const std::string& xml);
std::string WithoutProfiles(std::string xml, const std::set<std::string>& names);
void LogLost(const std::string& topic, int total, int change);
void LogFlowTimeout(const std::string& topic, std::chrono::milliseconds timeout);
void LogCallbackError(const std::string& topic, const char* what);
// The any-writer companion of a reader was made (or could not be).
void LogCompanion(const std::string& topic, bool made);
// ROS 2's DDS name of a type: "magnav::msg::GradiometerSample" -> "magnav::msg::dds_::GradiometerSample_".
std::string Ros2TypeName(const std::string& type_name);
// The any-writer companion's QoS: `q` with BEST_EFFORT and VOLATILE; none if
// `q` already is both (it then matches every writer itself).
std::optional<fdds::DataReaderQos> AnyWriterQos(const fdds::DataReaderQos& q);
WriterGuid GuidOf(const eprosima::fastrtps::rtps::GUID_t& guid);
WriterGuid GuidOf(const eprosima::fastrtps::rtps::InstanceHandle_t& handle);
bool WaitUntil(std::mutex& mu, std::condition_variable& cv, const std::function<bool()>& pred,
               std::chrono::milliseconds timeout);
}  // namespace internal

class Node;

// A typed writer on one topic.
template <class M>
class Writer {
 public:
  ~Writer() {
    if (!writer_) return;
    // Empty the history first, in one go: deleting a writer that still holds
    // its history (1000 samples per key) releases the samples one by one while
    // its heartbeat event walks the history for gaps under the same mutex; under
    // ThreadSanitizer a test process spent over 12 minutes there (CI,
    // 2026-11-25). What a VOLATILE or TRANSIENT_LOCAL writer held is gone with
    // it either way; a durable one (TRANSIENT, config/durable/) keeps its
    // history in its store for the next process, so it is left alone.
    const auto durability = writer_->get_qos().durability().kind;
    if (durability == fdds::VOLATILE_DURABILITY_QOS || durability == fdds::TRANSIENT_LOCAL_DURABILITY_QOS) {
      std::size_t removed = 0;
      writer_->clear_history(&removed);
    }
    node_publisher_->delete_datawriter(writer_);
  }
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // Publishes a sample; false if the middleware refused it (e.g. blocked too
  // long).
  bool Write(const M& sample) {
    if (flow_window_ > 0 && ++since_ack_ >= flow_window_) {
      since_ack_ = 0;
      // A reader that does not acknowledge in time (too slow, or dead and not
      // yet forgotten by discovery) must not stop the producer: counted,
      // logged, and the sample is written anyway (that reader may lose some).
      if (!WaitForAcknowledgments(flow_timeout_)) {
        ++stats_.flow_timeouts;
        internal::LogFlowTimeout(topic_, flow_timeout_);
      }
    }
    M copy = sample;  // Fast DDS takes a non-const pointer
    const bool ok = writer_->write(&copy);
    if (ok) ++stats_.samples;
    return ok;
  }
  // Ends the instance (key) of `sample`: the writer forgets its history, and
  // readers see it as not alive. For keys that never come back (a track that
  // ended: track ids are never reused), so that a writer running for weeks
  // does not run into its profile's max_instances. False if refused.
  bool Unregister(const M& sample) {
    M copy = sample;
    return writer_->unregister_instance(&copy, eprosima::fastrtps::rtps::c_InstanceHandle_Unknown) ==
           eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK;
  }
  // Flow control for senders that publish faster than readers may take (a
  // file replayed without pacing): every `window` samples, wait until every
  // matched reader has acknowledged all of them (at most `timeout`; then it
  // goes on, logged and counted in stats().flow_timeouts). With a KEEP_LAST
  // history this is what keeps a burst longer than the history from
  // overwriting samples a slow reader has not received yet. Keep window below
  // the history depth.
  // window 0 turns it off (the default: live streams are paced by the sensor).
  void SetFlowControl(int window, std::chrono::milliseconds timeout) {
    flow_window_ = window;
    flow_timeout_ = timeout;
    since_ack_ = 0;
  }
  // Waits until at least n readers are matched.
  bool WaitForMatched(int n, std::chrono::milliseconds timeout) {
    return internal::WaitUntil(listener_.mu, listener_.cv, [&] { return stats_.matched.load() >= n; }, timeout);
  }
  // Waits until every matched reliable reader acknowledged every sample.
  bool WaitForAcknowledgments(std::chrono::milliseconds timeout) {
    const auto ms = timeout.count();
    return writer_->wait_for_acknowledgments(
               eprosima::fastrtps::Duration_t(static_cast<int32_t>(ms / 1000),
                                              static_cast<uint32_t>((ms % 1000) * 1000000))) ==
           eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK;
  }
  const EndpointStats& stats() const { return stats_; }
  const std::string& topic() const { return topic_; }
  // The QoS in force (from the profile).
  fdds::DataWriterQos qos() const { return writer_->get_qos(); }

 private:
  friend class Node;
  struct Listener : fdds::DataWriterListener {
    Writer* self = nullptr;
    std::mutex mu;
    std::condition_variable cv;
    void on_publication_matched(fdds::DataWriter*, const fdds::PublicationMatchedStatus& s) override {
      {
        std::lock_guard<std::mutex> lk(mu);
        self->stats_.matched = s.current_count;
      }
      cv.notify_all();
    }
    void on_offered_incompatible_qos(fdds::DataWriter*, const fdds::OfferedIncompatibleQosStatus& s) override {
      ++self->stats_.incompatible_qos;
      internal::LogIncompatible(self->topic_, "writer", s.last_policy_id);
    }
  };
  Writer(fdds::Publisher* pub, fdds::Topic* topic, const std::string& profile) : node_publisher_(pub) {
    topic_ = topic->get_name();
    listener_.self = this;
    writer_ = pub->create_datawriter(topic, internal::WriterQos(pub, profile), &listener_);
    if (!writer_) throw DdsError("cannot create a writer on '" + topic_ + "' with profile '" + profile + "'");
  }
  fdds::Publisher* node_publisher_;
  fdds::DataWriter* writer_ = nullptr;
  int flow_window_ = 0;
  int since_ack_ = 0;
  std::chrono::milliseconds flow_timeout_{0};
  std::string topic_;
  EndpointStats stats_;
  Listener listener_;
};

namespace internal {

// Takes every sample `r` holds now into `sample` / `info`, one at a time:
// calls good() for each valid one and bad(n) for n payloads the type support
// refused (CheckedPubSubType, topics.h). Fast DDS 2.9.1 drops a refused
// payload inside take_next_sample and goes on to the next change in the same
// call: one take can refuse bad payloads and still return a good sample (when
// they came in one burst, as a late joiner's history or a repaired loss
// does), or answer NO_DATA after refusing (more may follow: take on).
template <class M, class Bad, class Good>
void TakeEach(fdds::DataReader* r, M& sample, fdds::SampleInfo& info, Bad&& bad, Good&& good) {
  while (true) {
    // Cleared first: Fast DDS may deserialise on this thread outside a take
    // (for a key).
    (void)TakeDeserializeFailures();
    const auto rc = r->take_next_sample(&sample, &info);
    const int refused = TakeDeserializeFailures();
    if (refused > 0) bad(refused);
    if (rc != eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
      if (refused > 0) continue;
      break;
    }
    if (info.valid_data) good();
  }
}

}  // namespace internal

// A typed reader on one topic; the callback runs on a middleware thread for
// every sample received. An exception thrown by the callback is caught,
// logged and counted: one bad sample never stops the reader.
//
// Any writer's QoS. A reader listens with its profile's DataReader (RELIABLE,
// TRANSIENT_LOCAL for magnav's streams: losses repaired, a transient-local
// writer's history after a restart) and, as soon as a writer appears that
// this reader cannot match for its reliability or durability (a stock
// driver's RELIABLE/VOLATILE — Cyclone DDS's default — or BEST_EFFORT — ROS
// 2's sensor-data QoS), an "any writer" companion with the same history and
// limits but BEST_EFFORT and VOLATILE, which matches every writer. The
// companion is made then (on its own thread, not in the middleware's
// callback) and kept: in a field with magnav writers only there is none,
// and no sample comes twice. While it exists, a writer both DataReaders
// match is served by the profile's alone and each sample is handed on once,
// by writer GUID and RTPS sequence number (DeliveryFilter). Not made when the
// profile already is BEST_EFFORT and VOLATILE or NodeOptions::any_writer is
// off. The callback is never called from two threads at once.
template <class M>
class Reader {
 public:
  using Callback = std::function<void(const M&, const fdds::SampleInfo&)>;
  ~Reader() {
    std::thread maker;
    {
      std::lock_guard<std::mutex> lk(companion_mu_);
      closing_ = true;
      maker = std::move(companion_thread_);
    }
    if (maker.joinable()) maker.join();
    for (Endpoint* e : {&profile_, &companion_}) {
      if (e->reader) {
        e->reader->set_listener(nullptr);
        node_subscriber_->delete_datareader(e->reader);
      }
    }
  }
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  // Waits until at least n writers are matched (each counted once, by either DataReader).
  bool WaitForMatched(int n, std::chrono::milliseconds timeout) {
    return internal::WaitUntil(mu_, cv_, [&] { return stats_.matched.load() >= n; }, timeout);
  }
  // Waits until at least n samples have been received in total.
  bool WaitForSamples(std::uint64_t n, std::chrono::milliseconds timeout) {
    return internal::WaitUntil(mu_, cv_, [&] { return stats_.samples.load() >= n; }, timeout);
  }
  const EndpointStats& stats() const { return stats_; }
  const std::string& topic() const { return topic_; }
  // The QoS in force (the profile's reader).
  fdds::DataReaderQos qos() const { return profile_.reader->get_qos(); }
  // Whether the any-writer companion exists (made when the first writer
  // this reader's profile cannot match appears).
  bool has_companion() const { return has_companion_; }
  // Makes the companion now rather than when the first writer needs it: for
  // a consumer that expects stock writers and must not lose their first
  // samples while the companion is made. No-op when it cannot have one.
  void ListenToAnyWriter() {
    if (any_qos_) StartCompanion();
  }
  // Waits until the companion exists.
  bool WaitForCompanion(std::chrono::milliseconds timeout) {
    return internal::WaitUntil(mu_, cv_, [&] { return has_companion_.load(); }, timeout);
  }
  // Writers matched by the companion only (best-effort or volatile ones).
  int companion_only_writers() const { return filter_.companion_only_writers(); }

 private:
  friend class Node;
  struct Endpoint : fdds::DataReaderListener {
    Reader* self = nullptr;
    bool companion = false;
    fdds::DataReader* reader = nullptr;
    M sample;
    void on_data_available(fdds::DataReader* r) override {
      fdds::SampleInfo info;
      internal::TakeEach(
          r, sample, info,
          [&](int bad) {
            // Which writer sent it is not known: the companion counts only
            // while it serves writers of its own (else both would count the
            // payload of a writer both match).
            if (!companion || self->filter_.companion_only_writers() > 0) {
              if (self->stats_.bad_payloads.fetch_add(static_cast<std::uint64_t>(bad)) == 0) {
                internal::LogBadPayload(self->topic_);
              }
            }
          },
          [&] { self->Deliver(companion, sample, info); });
    }
    void on_subscription_matched(fdds::DataReader*, const fdds::SubscriptionMatchedStatus& s) override {
      self->filter_.Matched(companion, internal::GuidOf(s.last_publication_handle), s.current_count_change);
      {
        std::lock_guard<std::mutex> lk(self->mu_);
        self->stats_.matched = self->filter_.matched_writers();
      }
      self->cv_.notify_all();
    }
    void on_sample_lost(fdds::DataReader*, const fdds::SampleLostStatus& s) override {
      // Best-effort delivery of a writer the profile's reader serves is
      // dropped anyway: the companion's losses count only for its own writers.
      if (companion && self->filter_.companion_only_writers() == 0) return;
      self->lost_[companion] = static_cast<std::uint64_t>(s.total_count);
      self->stats_.lost = self->lost_[0] + self->lost_[1];
      internal::LogLost(self->topic_, s.total_count, s.total_count_change);
    }
    void on_requested_incompatible_qos(fdds::DataReader*, const fdds::RequestedIncompatibleQosStatus& s) override {
      // A writer the profile's reader cannot match for its reliability or
      // durability (a volatile or best-effort one) is the companion's: made
      // now if need be. Only other incompatibilities (and the companion's)
      // are real.
      using P = fdds::QosPolicyId_t;
      const auto policy = static_cast<P>(s.last_policy_id);
      if (!companion && self->any_qos_ &&
          (policy == P::DURABILITY_QOS_POLICY_ID || policy == P::RELIABILITY_QOS_POLICY_ID)) {
        self->StartCompanion();
        return;
      }
      ++self->stats_.incompatible_qos;
      internal::LogIncompatible(self->topic_, "reader", s.last_policy_id);
    }
  };
  Reader(fdds::Subscriber* sub, fdds::Topic* topic, const std::string& profile, bool any_writer, Callback cb)
      : node_subscriber_(sub), callback_(std::move(cb)) {
    topic_ = topic->get_name();
    profile_.self = companion_.self = this;
    companion_.companion = true;
    const fdds::DataReaderQos qos = internal::ReaderQos(sub, profile);
    any_qos_ = any_writer ? internal::AnyWriterQos(qos) : std::nullopt;  // before the reader: its listener reads it
    topic_entity_ = topic;
    profile_.reader = sub->create_datareader(topic, qos, &profile_);
    if (!profile_.reader) throw DdsError("cannot create a reader on '" + topic_ + "' with profile '" + profile + "'");
  }
  // Makes the companion once, on a thread of its own (creating a DataReader
  // inside a middleware callback is not safe).
  // companion_mu_ is held only to start or take the thread, never across a
  // middleware call: this runs inside Fast DDS's discovery callbacks (their
  // locks held), and create_datareader takes those locks (ThreadSanitizer
  // found the inversion when the maker held it).
  void StartCompanion() {
    std::lock_guard<std::mutex> lk(companion_mu_);
    if (companion_started_ || closing_) return;
    companion_started_ = true;
    companion_thread_ = std::thread([this] {
      {
        std::lock_guard<std::mutex> closing_lk(companion_mu_);
        if (closing_) return;
      }
      // The destructor joins this thread before it deletes anything.
      companion_.reader = node_subscriber_->create_datareader(topic_entity_, *any_qos_, &companion_);
      if (!companion_.reader) {
        internal::LogCompanion(topic_, false);
        return;
      }
      {
        std::lock_guard<std::mutex> wait_lk(mu_);
        has_companion_ = true;
      }
      cv_.notify_all();
      internal::LogCompanion(topic_, true);
    });
  }
  void Deliver(bool companion, const M& m, const fdds::SampleInfo& info) {
    std::lock_guard<std::mutex> deliver(deliver_mu_);
    const auto verdict = filter_.Offer(companion, internal::GuidOf(info.sample_identity.writer_guid()),
                                       info.sample_identity.sequence_number().to64long());
    if (verdict == DeliveryFilter::Verdict::kServedByProfileReader) return;
    if (verdict == DeliveryFilter::Verdict::kDuplicate) {
      ++stats_.duplicates;
      return;
    }
    if (companion) ++stats_.via_any_writer;
    try {
      if (callback_) callback_(m, info);
    } catch (const std::exception& e) {
      ++stats_.callback_errors;
      internal::LogCallbackError(topic_, e.what());
    } catch (...) {
      ++stats_.callback_errors;
      internal::LogCallbackError(topic_, "unknown exception");
    }
    {
      std::lock_guard<std::mutex> lk(mu_);
      ++stats_.samples;
    }
    cv_.notify_all();
  }
  fdds::Subscriber* node_subscriber_;
  std::string topic_;
  Callback callback_;
  EndpointStats stats_;
  DeliveryFilter filter_;
  std::optional<fdds::DataReaderQos> any_qos_;  // the companion's; none: never made
  fdds::Topic* topic_entity_ = nullptr;
  std::atomic<bool> has_companion_{false};
  std::mutex companion_mu_;  // companion_started_, closing_, companion_thread_ (never held across a middleware call)
  bool companion_started_ = false, closing_ = false;
  std::thread companion_thread_;
  std::atomic<std::uint64_t> lost_[2] = {0, 0};
  std::mutex deliver_mu_;  // one callback at a time, and the filter's verdict with it
  std::mutex mu_;          // for the waits
  std::condition_variable cv_;
  Endpoint profile_, companion_;
};

class Node {
 public:
  // Throws DdsError (bad options, profile not found, participant refused).
  explicit Node(const NodeOptions& options = {});
  ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  int domain_id() const { return domain_id_; }

  template <class M>
  std::unique_ptr<Writer<M>> CreateWriter(const std::string& topic_name = TopicTraits<M>::kTopic,
                                          const std::string& profile = TopicTraits<M>::kWriterProfile) {
    fdds::Topic* t = GetTopic(WireTopicName(topic_name), RegisterType<M>());
    return std::unique_ptr<Writer<M>>(new Writer<M>(publisher_, t, profile));
  }

  template <class M>
  std::unique_ptr<Reader<M>> CreateReader(typename Reader<M>::Callback cb,
                                          const std::string& topic_name = TopicTraits<M>::kTopic,
                                          const std::string& profile = TopicTraits<M>::kReaderProfile) {
    fdds::Topic* t = GetTopic(WireTopicName(topic_name), RegisterType<M>());
    return std::unique_ptr<Reader<M>>(new Reader<M>(subscriber_, t, profile, any_writer_, std::move(cb)));
  }

 private:
  template <class M>
  std::string RegisterType() {
    fdds::TypeSupport ts(new typename TopicTraits<M>::PubSubType());
    const std::string name = ros2_names_ ? internal::Ros2TypeName(ts.get_type_name()) : ts.get_type_name();
    if (!participant_->find_type(name).empty()) return name;
    if (ts.register_type(participant_, name) != eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
      throw DdsError("cannot register type " + name);
    }
    return name;
  }
  fdds::Topic* GetTopic(const std::string& name, const std::string& type);
  std::string WireTopicName(const std::string& name) const { return ros2_names_ ? "rt/" + name : name; }

  int domain_id_ = 0;
  bool ros2_names_ = false;
  bool any_writer_ = true;
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
  std::mutex topics_mu_;
};

}  // namespace magnav::dds
