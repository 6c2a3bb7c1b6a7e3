// A small MCAP writer and reader (https://mcap.dev/spec, format version 0),
// written from the public specification: Debian 12 packages no MCAP C++
// library. No DDS here: messages are opaque bytes (magnav writes the CDR its
// type support produces, see tools/mcap_topics.h).
//
// File layout the Writer produces (docs/PROTOCOL.md, "Recordings (MCAP)"):
//   magic, Header, Metadata, [Schema, Channel]..., then per flush a Chunk
//   (Message records, compressed with zstd or lz4 or not at all) followed by
//   its Message Index records (one per channel in the chunk), Data End;
//   summary: Schemas, Channels, Statistics, Metadata Index, Chunk Indexes;
//   one Summary Offset per group; Footer; magic. Every CRC is filled in.
// Times are uint64 nanoseconds (log_time: when received, publish_time: the
// message's source time stamp).
#pragma once

#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace magnav::mcap {

using KeyValues = std::vector<std::pair<std::string, std::string>>;  // Map<string, string>, in order

struct Schema {
  std::uint16_t id = 0;
  std::string name;      // e.g. the DDS type name "magnav::msg::GradiometerSample"
  std::string encoding;  // e.g. "omgidl"
  std::string data;      // e.g. the IDL text
};

struct Channel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;  // e.g. "cdr"
  KeyValues metadata;
};

struct Message {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;      // ns
  std::uint64_t publish_time = 0;  // ns
  std::string data;
};

struct Metadata {
  std::string name;
  KeyValues values;
};

struct Statistics {
  std::uint64_t message_count = 0;
  std::uint16_t schema_count = 0;
  std::uint32_t channel_count = 0;
  std::uint32_t attachment_count = 0;
  std::uint32_t metadata_count = 0;
  std::uint32_t chunk_count = 0;
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::map<std::uint16_t, std::uint64_t> channel_message_counts;
};

enum class Compression { kNone, kZstd, kLz4 };
// "" / "zstd" / "lz4" as in the Chunk record; nullopt for any other name.
std::optional<Compression> CompressionFromName(const std::string& name);
const char* CompressionName(Compression c);

// CRC-32 (ISO-HDLC, as zlib's crc32), continuing from `crc` (0 to start).
std::uint32_t Crc32(const void* data, std::size_t n, std::uint32_t crc = 0);

struct WriterOptions {
  Compression compression = Compression::kZstd;
  int zstd_level = 1;
  // A chunk is closed once its records reach this size (and on Flush()).
  std::size_t chunk_size = 4u << 20;
  std::string profile;  // Header profile ("" = none)
  std::string library;  // Header library, e.g. "magnav 0.1.0"
};

// Writes to "PATH.tmp-PID-N" in the same directory, renamed to PATH by Close()
// (an output is complete or absent); destroyed without Close() it removes the
// temporary. Not thread-safe (callers serialise). Throws InputError
// ("PATH: ...") when the file cannot be created or written.
class Writer {
 public:
  Writer(const std::string& path, WriterOptions options);
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // Returns the new schema's / channel's id (1, 2, ...). Written to the data
  // section at once (into the open chunk if one is open) and to the summary.
  std::uint16_t AddSchema(const std::string& name, const std::string& encoding, const std::string& data);
  std::uint16_t AddChannel(std::uint16_t schema_id, const std::string& topic,
                           const std::string& message_encoding, const KeyValues& metadata);
  // A Metadata record in the data section (outside chunks) and its index.
  void AddMetadata(const std::string& name, const KeyValues& values);
  void Write(const Message& m) {
    Write(m.channel_id, m.sequence, m.log_time, m.publish_time, m.data.data(), m.data.size());
  }
  void Write(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time,
             std::uint64_t publish_time, const void* data, std::size_t size);
  // Closes the open chunk (with its message indexes) and hands the bytes to
  // the system: after kill -9 the temporary holds every chunk flushed.
  void Flush();
  // Data End, summary, footer; renames the temporary to the path.
  void Close();

  // Bytes in the file so far (whole records; the open chunk not included).
  std::uint64_t bytes_written() const { return offset_; }
  // The file size if it were closed now, roughly (the open chunk uncompressed).
  std::uint64_t size_estimate() const { return offset_ + chunk_.size(); }
  // Bytes of message data written (uncompressed payloads).
  std::uint64_t message_bytes() const { return message_bytes_; }
  const Statistics& statistics() const { return stats_; }
  const std::string& path() const { return path_; }
  const std::string& temp_path() const { return temp_path_; }

 private:
  void WriteRaw(const std::string& bytes);
  void CloseChunk();

  std::string path_, temp_path_;
  WriterOptions options_;
  std::FILE* file_ = nullptr;
  bool closed_ = false;
  std::uint64_t offset_ = 0;
  std::uint32_t data_crc_ = 0;
  std::uint64_t message_bytes_ = 0;
  std::vector<Schema> schemas_;
  std::vector<Channel> channels_;
  std::vector<std::string> metadata_index_;  // serialised Metadata Index records
  std::vector<std::string> chunk_index_;     // serialised Chunk Index records
  Statistics stats_;
  // The open chunk.
  std::string chunk_;
  std::uint64_t chunk_start_ = 0, chunk_end_ = 0;
  bool chunk_has_messages_ = false;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index_entries_;
};

// What a read found, beside the messages handed to the callback.
struct ReadSummary {
  std::string profile, library;
  std::vector<Schema> schemas;  // by id order of appearance
  std::vector<Channel> channels;
  std::vector<Metadata> metadata;
  std::optional<Statistics> statistics;  // from the summary (complete files)
  std::uint64_t messages = 0;            // messages handed on
  std::uint32_t chunks = 0;              // complete chunks read
  // Empty for a complete file; else what was missing ("FILE: cut short at
  // byte N (of a Chunk record): ... missing"). The messages of every complete
  // chunk before the cut were handed on.
  std::string truncated;
};

const Channel* FindChannel(const ReadSummary& s, std::uint16_t id);
const Schema* FindSchema(const ReadSummary& s, std::uint16_t id);

struct ReaderLimits {
  // A chunk claiming more uncompressed bytes is refused before allocating.
  std::uint64_t max_chunk_bytes = 1ull << 30;
  // A record (outside chunks) longer than this is refused.
  std::uint64_t max_record_bytes = 1ull << 30;
};

// Reads a file from start to end (the data section in order; the summary is
// checked against what was read). `on_message` gets each message with the
// summary so far (its channel and schema are in it). Invalid content throws
// InputError "FILE: what is wrong"; a file cut short is read up to its last
// complete chunk and the summary's `truncated` says what is missing.
ReadSummary Read(const std::string& path,
                 const std::function<void(const Message&, const ReadSummary&)>& on_message,
                 const ReaderLimits& limits = {});
// The same on bytes in memory (`name` is the file name in messages): the fuzz target.
ReadSummary ReadBytes(const std::string& name, const std::string& bytes,
                      const std::function<void(const Message&, const ReadSummary&)>& on_message,
                      const ReaderLimits& limits = {});

// True if the file starts with the MCAP magic.
bool HasMcapMagic(const std::string& path);

}  // namespace magnav::mcap
