// MCAP writer and reader (see mcap.h). Record layouts follow the
// specification's tables: <opcode u8><length u64><content>, little-endian
// integers, strings and maps with a uint32 byte length.
#include "magnav/mcap/mcap.h"

#include <fcntl.h>
#include <lz4frame.h>
#include <unistd.h>
#include <zstd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <fstream>
#include <string_view>

#include "magnav/core/error.h"

namespace magnav::mcap {
namespace {

constexpr char kMagic[8] = {'\x89', 'M', 'C', 'A', 'P', '0', '\r', '\n'};

enum Op : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

const char* OpName(std::uint8_t op) {
  switch (op) {
    case kHeader:
      return "Header";
    case kFooter:
      return "Footer";
    case kSchema:
      return "Schema";
    case kChannel:
      return "Channel";
    case kMessage:
      return "Message";
    case kChunk:
      return "Chunk";
    case kMessageIndex:
      return "Message Index";
    case kChunkIndex:
      return "Chunk Index";
    case kAttachment:
      return "Attachment";
    case kAttachmentIndex:
      return "Attachment Index";
    case kStatistics:
      return "Statistics";
    case kMetadata:
      return "Metadata";
    case kMetadataIndex:
      return "Metadata Index";
    case kSummaryOffset:
      return "Summary Offset";
    case kDataEnd:
      return "Data End";
    default:
      return "unknown";
  }
}

// ---- serialisation ---------------------------------------------------------

struct Buf {
  std::string s;
  void U8(std::uint8_t v) { s.push_back(static_cast<char>(v)); }
  template <class T>
  void Le(T v) {
    for (std::size_t i = 0; i < sizeof(T); ++i)
      s.push_back(static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * i)) & 0xff));
  }
  void U16(std::uint16_t v) { Le(v); }
  void U32(std::uint32_t v) { Le(v); }
  void U64(std::uint64_t v) { Le(v); }
  void Str(const std::string& v) {
    U32(static_cast<std::uint32_t>(v.size()));
    s += v;
  }
  void Map(const KeyValues& kv) {
    Buf b;
    for (const auto& [k, v] : kv) {
      b.Str(k);
      b.Str(v);
    }
    Str(b.s);
  }
};

std::string Record(std::uint8_t op, const std::string& content) {
  Buf b;
  b.U8(op);
  b.U64(content.size());
  b.s += content;
  return b.s;
}

std::string SchemaRecord(const Schema& s) {
  Buf b;
  b.U16(s.id);
  b.Str(s.name);
  b.Str(s.encoding);
  b.Str(s.data);
  return Record(kSchema, b.s);
}

std::string ChannelRecord(const Channel& c) {
  Buf b;
  b.U16(c.id);
  b.U16(c.schema_id);
  b.Str(c.topic);
  b.Str(c.message_encoding);
  b.Map(c.metadata);
  return Record(kChannel, b.s);
}

std::array<std::uint32_t, 256> MakeCrcTable() {
  std::array<std::uint32_t, 256> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    t[i] = c;
  }
  return t;
}

// ---- parsing ---------------------------------------------------------------

// Thrown by Cursor when a record's content is shorter than its fields.
struct Short {};

struct Cursor {
  std::string_view d;
  std::size_t p = 0;
  std::size_t left() const { return d.size() - p; }
  void Need(std::uint64_t n) const {
    if (n > left()) throw Short{};
  }
  template <class T>
  T Le() {
    Need(sizeof(T));
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i)
      v |= static_cast<std::uint64_t>(static_cast<unsigned char>(d[p + i])) << (8 * i);
    p += sizeof(T);
    return static_cast<T>(v);
  }
  std::uint8_t U8() { return Le<std::uint8_t>(); }
  std::uint16_t U16() { return Le<std::uint16_t>(); }
  std::uint32_t U32() { return Le<std::uint32_t>(); }
  std::uint64_t U64() { return Le<std::uint64_t>(); }
  std::string_view Bytes(std::uint64_t n) {
    Need(n);
    std::string_view v = d.substr(p, n);
    p += n;
    return v;
  }
  std::string Str() { return std::string(Bytes(U32())); }
  KeyValues Map() {
    Cursor m{Bytes(U32())};
    KeyValues kv;
    while (m.left() > 0) {
      std::string k = m.Str();
      kv.emplace_back(std::move(k), m.Str());
    }
    return kv;
  }
};

// A log time: UTC when it is one (after 2001), else seconds.
std::string FormatTime(std::uint64_t ns) {
  char b[64];
  if (ns >= 1000000000000000000ull) {
    const std::time_t t = static_cast<std::time_t>(ns / 1000000000ull);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char d[32];
    std::strftime(d, sizeof d, "%Y-%m-%dT%H:%M:%S", &tm);
    std::snprintf(b, sizeof b, "%s.%03lluZ", d, static_cast<unsigned long long>((ns / 1000000ull) % 1000));
  } else {
    std::snprintf(b, sizeof b, "%.3f s", static_cast<double>(ns) * 1e-9);
  }
  return b;
}

// Where the bytes come from: a file (read on demand) or memory.
class Source {
 public:
  virtual ~Source() = default;
  virtual std::uint64_t size() const = 0;
  // Exactly n bytes at offset (the caller checked the bounds).
  virtual std::string_view Read(std::uint64_t offset, std::uint64_t n) = 0;
};

class MemorySource : public Source {
 public:
  explicit MemorySource(const std::string& b) : b_(b) {}
  std::uint64_t size() const override { return b_.size(); }
  std::string_view Read(std::uint64_t offset, std::uint64_t n) override {
    return std::string_view(b_).substr(offset, n);
  }

 private:
  const std::string& b_;
};

class FileSource : public Source {
 public:
  explicit FileSource(const std::string& path) : in_(path, std::ios::binary) {
    if (!in_) throw InputError(path + ": cannot open file (" + std::strerror(errno) + ")");
    in_.seekg(0, std::ios::end);
    size_ = static_cast<std::uint64_t>(in_.tellg());
    path_ = path;
  }
  std::uint64_t size() const override { return size_; }
  std::string_view Read(std::uint64_t offset, std::uint64_t n) override {
    buf_.resize(n);
    in_.seekg(static_cast<std::streamoff>(offset));
    in_.read(buf_.data(), static_cast<std::streamsize>(n));
    if (!in_) throw InputError(path_ + ": read error at byte " + std::to_string(offset));
    return buf_;
  }

 private:
  std::ifstream in_;
  std::string path_;
  std::uint64_t size_ = 0;
  std::string buf_;
};

class Parser {
 public:
  Parser(const std::string& name, Source& src,
         const std::function<void(const Message&, const ReadSummary&)>& cb, const ReaderLimits& limits)
      : name_(name), src_(src), cb_(cb), limits_(limits) {}

  ReadSummary Run() {
    const std::uint64_t size = src_.size();
    if (size == 0) Fail("empty file (not MCAP)");
    const std::uint64_t head = std::min<std::uint64_t>(size, 8);
    if (std::memcmp(src_.Read(0, head).data(), kMagic, head) != 0) {
      Fail("not an MCAP file (the first 8 bytes are not the MCAP magic \\x89MCAP0\\r\\n)");
    }
    if (size < 8) return Truncated(size, "inside the magic");
    std::uint64_t pos = 8;
    bool data_end = false;
    bool first = true;
    while (true) {
      if (pos + 9 > size) {
        return Truncated(pos, pos == size ? "at a record boundary" : "inside a record's opcode and length");
      }
      const std::string_view rh = src_.Read(pos, 9);
      Cursor hc{rh};
      const std::uint8_t op = hc.U8();
      const std::uint64_t len = hc.U64();
      if (first && op != kHeader)
        Fail("byte 8: the first record is a " + std::string(OpName(op)) + " record, not a Header");
      first = false;
      const std::uint64_t max = op == kChunk ? limits_.max_chunk_bytes : limits_.max_record_bytes;
      if (len > max) {
        Fail("byte " + std::to_string(pos) + ": a " + OpName(op) + " record of " + std::to_string(len) +
             " bytes is over the limit of " + std::to_string(max));
      }
      if (len > size - pos - 9) {
        return Truncated(pos, std::string("inside a ") + OpName(op) + " record (" +
                                  std::to_string(size - pos - 9) + " of its " + std::to_string(len) +
                                  " bytes present)");
      }
      at_ = pos;
      const std::string content(src_.Read(pos + 9, len));
      const std::uint64_t next = pos + 9 + len;
      if (op == kFooter) {
        Footer(content, next, size);
        return std::move(s_);
      }
      if (!data_end) {
        if (op == kDataEnd) {
          data_end = true;
          summary_start_ = next;
        } else {
          DataRecord(op, content);
        }
      } else {
        SummaryRecord(op, content);
      }
      pos = next;
    }
  }

 private:
  [[noreturn]] void Fail(const std::string& what) const { throw InputError(name_ + ": " + what); }
  std::string Where(std::uint8_t op) const {
    return "byte " + std::to_string(at_) + ": " + OpName(op) + " record: ";
  }

  ReadSummary Truncated(std::uint64_t pos, const std::string& where) {
    MarkTruncated(pos, where);
    return std::move(s_);
  }
  void MarkTruncated(std::uint64_t pos, const std::string& where) {
    std::string missing = footer_ ? "the closing magic"
                          : summary_start_
                              ? "the summary (statistics, indexes) and the footer"
                              : "the rest of the data section, Data End, the summary (statistics, chunk "
                                "and message indexes) and the footer";
    s_.truncated = name_ + ": cut short at byte " + std::to_string(pos) + " (" + where + "): read " +
                   std::to_string(s_.chunks) + " complete chunk(s), " + std::to_string(s_.messages) +
                   " message(s)" + (s_.messages ? " up to log time " + FormatTime(last_log_) : "") +
                   "; missing: " + missing;
  }

  void AddSchema(Schema sc, std::uint8_t op) {
    if (sc.id == 0) return;  // invalid by the spec: ignored
    for (const Schema& o : s_.schemas) {
      if (o.id == sc.id) {
        if (o.name != sc.name || o.encoding != sc.encoding || o.data != sc.data) {
          Fail(Where(op) + "schema " + std::to_string(sc.id) + " differs from an earlier one of the same id");
        }
        return;
      }
    }
    s_.schemas.push_back(std::move(sc));
  }
  void AddChannel(Channel c, std::uint8_t op) {
    if (c.schema_id != 0 && !FindSchema(s_, c.schema_id)) {
      Fail(Where(op) + "channel " + std::to_string(c.id) + " refers to schema " +
           std::to_string(c.schema_id) + ", which is not defined before it");
    }
    for (const Channel& o : s_.channels) {
      if (o.id == c.id) {
        if (o.topic != c.topic || o.schema_id != c.schema_id || o.message_encoding != c.message_encoding) {
          Fail(Where(op) + "channel " + std::to_string(c.id) + " differs from an earlier one of the same id");
        }
        return;
      }
    }
    s_.channels.push_back(std::move(c));
  }

  // Schema, Channel or Message (in a chunk or not); false for other opcodes.
  bool Common(std::uint8_t op, std::string_view content) {
    Cursor c{content};
    try {
      if (op == kSchema) {
        Schema sc;
        sc.id = c.U16();
        sc.name = c.Str();
        sc.encoding = c.Str();
        sc.data = c.Str();
        AddSchema(std::move(sc), op);
        return true;
      }
      if (op == kChannel) {
        Channel ch;
        ch.id = c.U16();
        ch.schema_id = c.U16();
        ch.topic = c.Str();
        ch.message_encoding = c.Str();
        ch.metadata = c.Map();
        AddChannel(std::move(ch), op);
        return true;
      }
      if (op == kMessage) {
        Message m;
        m.channel_id = c.U16();
        m.sequence = c.U32();
        m.log_time = c.U64();
        m.publish_time = c.U64();
        m.data = std::string(c.Bytes(c.left()));
        if (!FindChannel(s_, m.channel_id)) {
          Fail(Where(op) + "message on channel " + std::to_string(m.channel_id) +
               ", which is not defined before it");
        }
        ++s_.messages;
        last_log_ = m.log_time;
        if (cb_) cb_(m, s_);
        return true;
      }
    } catch (const Short&) {
      Fail(Where(op) + "shorter than its fields");
    }
    return false;
  }

  void DataRecord(std::uint8_t op, const std::string& content) {
    if (Common(op, content)) return;
    Cursor c{content};
    try {
      switch (op) {
        case kHeader:
          s_.profile = c.Str();
          s_.library = c.Str();
          return;
        case kChunk:
          Chunk(c);
          return;
        case kMetadata: {
          Metadata m;
          m.name = c.Str();
          m.values = c.Map();
          s_.metadata.push_back(std::move(m));
          return;
        }
        case kMessageIndex:
          c.U16();
          c.Bytes(c.U32());
          return;
        case kAttachment:
        default:
          return;  // attachments and unknown records are skipped
        case kFooter:
        case kChunkIndex:
        case kAttachmentIndex:
        case kStatistics:
        case kMetadataIndex:
        case kSummaryOffset:
          Fail(Where(op) + "not allowed in the data section");
      }
    } catch (const Short&) {
      Fail(Where(op) + "shorter than its fields");
    }
  }

  void Chunk(Cursor& c) {
    const std::uint64_t start = c.U64(), end = c.U64(), usize = c.U64();
    const std::uint32_t crc = c.U32();
    const std::string comp = c.Str();
    const std::uint64_t csize = c.U64();
    const std::string_view records = c.Bytes(csize);
    (void)start;
    (void)end;
    const std::optional<Compression> kind = CompressionFromName(comp);
    if (!kind) Fail(Where(kChunk) + "unknown compression '" + comp + "'");
    if (usize > limits_.max_chunk_bytes) {
      Fail(Where(kChunk) + "claims " + std::to_string(usize) + " uncompressed bytes, over the limit of " +
           std::to_string(limits_.max_chunk_bytes));
    }
    std::string plain;
    if (*kind == Compression::kNone) {
      if (usize != csize)
        Fail(Where(kChunk) + "uncompressed_size " + std::to_string(usize) + " != records length " +
             std::to_string(csize));
      plain.assign(records);
    } else if (*kind == Compression::kZstd) {
      plain.resize(usize);
      const std::size_t n = ZSTD_decompress(plain.data(), plain.size(), records.data(), records.size());
      if (ZSTD_isError(n)) Fail(Where(kChunk) + "zstd: " + ZSTD_getErrorName(n));
      if (n != usize)
        Fail(Where(kChunk) + "decompressed to " + std::to_string(n) + " bytes, uncompressed_size says " +
             std::to_string(usize));
    } else {
      plain.resize(usize);
      LZ4F_dctx* ctx = nullptr;
      if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION)))
        Fail("lz4: cannot create a context");
      std::size_t in_pos = 0, out_pos = 0;
      std::size_t ret = 1;
      while (ret != 0 && in_pos < records.size() && out_pos <= plain.size()) {
        std::size_t in_n = records.size() - in_pos, out_n = plain.size() - out_pos;
        ret = LZ4F_decompress(ctx, plain.data() + out_pos, &out_n, records.data() + in_pos, &in_n, nullptr);
        if (LZ4F_isError(ret)) {
          const std::string why = LZ4F_getErrorName(ret);
          LZ4F_freeDecompressionContext(ctx);
          Fail(Where(kChunk) + "lz4: " + why);
        }
        in_pos += in_n;
        out_pos += out_n;
        if (in_n == 0 && out_n == 0) break;
      }
      LZ4F_freeDecompressionContext(ctx);
      if (ret != 0 || out_pos != usize) {
        Fail(Where(kChunk) + "lz4 data decompressed to " + std::to_string(out_pos) +
             " bytes, uncompressed_size says " + std::to_string(usize));
      }
    }
    if (crc != 0 && Crc32(plain.data(), plain.size()) != crc)
      Fail(Where(kChunk) + "CRC mismatch of the uncompressed records");
    // The chunk is whole and checked: its records.
    const std::uint64_t chunk_at = at_;
    Cursor r{plain};
    while (r.left() > 0) {
      std::uint8_t op = 0;
      std::uint64_t len = 0;
      try {
        op = r.U8();
        len = r.U64();
        r.Need(len);
      } catch (const Short&) {
        Fail(Where(kChunk) + "a record inside the chunk runs past its end");
      }
      const std::string_view content = r.Bytes(len);
      if (op != kSchema && op != kChannel && op != kMessage) {
        Fail(Where(kChunk) + "a " + std::string(OpName(op)) +
             " record inside a chunk (only Schema, Channel, Message are allowed)");
      }
      Common(op, content);
      at_ = chunk_at;
    }
    ++s_.chunks;
  }

  void SummaryRecord(std::uint8_t op, const std::string& content) {
    Cursor c{content};
    try {
      switch (op) {
        case kStatistics: {
          Statistics st;
          st.message_count = c.U64();
          st.schema_count = c.U16();
          st.channel_count = c.U32();
          st.attachment_count = c.U32();
          st.metadata_count = c.U32();
          st.chunk_count = c.U32();
          st.message_start_time = c.U64();
          st.message_end_time = c.U64();
          Cursor m{c.Bytes(c.U32())};
          while (m.left() > 0) {
            const std::uint16_t id = m.U16();
            st.channel_message_counts[id] = m.U64();
          }
          s_.statistics = st;
          return;
        }
        case kSchema:
        case kChannel:
          Common(op, content);
          return;
        case kMessage:
        case kChunk:
        case kMessageIndex:
        case kMetadata:
        case kAttachment:
        case kHeader:
        case kDataEnd:
          Fail(Where(op) + "not allowed in the summary section");
        default:
          return;  // indexes: this reader reads in order
      }
    } catch (const Short&) {
      Fail(Where(op) + "shorter than its fields");
    }
  }

  void Footer(const std::string& content, std::uint64_t next, std::uint64_t size) {
    footer_ = true;
    Cursor c{content};
    try {
      c.U64();
      c.U64();
      c.U32();
    } catch (const Short&) {
      Fail(Where(kFooter) + "shorter than its fields");
    }
    if (next + 8 > size) {
      if (std::memcmp(src_.Read(next, size - next).data(), kMagic, size - next) != 0) {
        Fail("byte " + std::to_string(next) + ": the bytes after the footer are not the MCAP magic");
      }
      MarkTruncated(size, "inside the closing magic");
      return;
    }
    if (std::memcmp(src_.Read(next, 8).data(), kMagic, 8) != 0) {
      Fail("byte " + std::to_string(next) + ": the bytes after the footer are not the MCAP magic");
    }
    if (next + 8 != size)
      Fail("byte " + std::to_string(next + 8) + ": " + std::to_string(size - next - 8) +
           " byte(s) after the closing magic");
    if (s_.statistics && s_.statistics->message_count != s_.messages) {
      Fail("the Statistics record counts " + std::to_string(s_.statistics->message_count) +
           " messages, the data section holds " + std::to_string(s_.messages));
    }
  }

  std::string name_;
  Source& src_;
  const std::function<void(const Message&, const ReadSummary&)>& cb_;
  ReaderLimits limits_;
  ReadSummary s_;
  std::uint64_t at_ = 0;
  std::uint64_t last_log_ = 0;
  std::uint64_t summary_start_ = 0;
  bool footer_ = false;
};

}  // namespace

std::optional<Compression> CompressionFromName(const std::string& name) {
  if (name.empty() || name == "none") return Compression::kNone;
  if (name == "zstd") return Compression::kZstd;
  if (name == "lz4") return Compression::kLz4;
  return std::nullopt;
}

const char* CompressionName(Compression c) {
  switch (c) {
    case Compression::kZstd:
      return "zstd";
    case Compression::kLz4:
      return "lz4";
    default:
      return "";
  }
}

std::uint32_t Crc32(const void* data, std::size_t n, std::uint32_t crc) {
  static const std::array<std::uint32_t, 256> table = MakeCrcTable();
  const auto* p = static_cast<const unsigned char*>(data);
  crc = ~crc;
  for (std::size_t i = 0; i < n; ++i) crc = table[(crc ^ p[i]) & 0xff] ^ (crc >> 8);
  return ~crc;
}

const Channel* FindChannel(const ReadSummary& s, std::uint16_t id) {
  for (const Channel& c : s.channels) {
    if (c.id == id) return &c;
  }
  return nullptr;
}

const Schema* FindSchema(const ReadSummary& s, std::uint16_t id) {
  for (const Schema& c : s.schemas) {
    if (c.id == id) return &c;
  }
  return nullptr;
}

// ---- Writer ----------------------------------------------------------------

Writer::Writer(const std::string& path, WriterOptions options) : path_(path), options_(std::move(options)) {
  for (int attempt = 0;; ++attempt) {
    temp_path_ = path + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(attempt);
    const int fd = ::open(temp_path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) {
      file_ = ::fdopen(fd, "wb");
      if (!file_) ::close(fd);
      break;
    }
    if (errno != EEXIST || attempt >= 100)
      throw InputError(path + ": cannot open file for writing (" + std::strerror(errno) + ")");
  }
  if (!file_) {
    ::unlink(temp_path_.c_str());
    throw InputError(path + ": cannot open file for writing");
  }
  WriteRaw(std::string(kMagic, 8));
  Buf h;
  h.Str(options_.profile);
  h.Str(options_.library);
  WriteRaw(Record(kHeader, h.s));
}

Writer::~Writer() {
  if (file_) std::fclose(file_);
  if (!closed_) ::unlink(temp_path_.c_str());
}

void Writer::WriteRaw(const std::string& bytes) {
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) {
    throw InputError(path_ + ": write failed (" + std::strerror(errno) + ")");
  }
  data_crc_ = Crc32(bytes.data(), bytes.size(), data_crc_);
  offset_ += bytes.size();
}

std::uint16_t Writer::AddSchema(const std::string& name, const std::string& encoding,
                                const std::string& data) {
  Schema s{static_cast<std::uint16_t>(schemas_.size() + 1), name, encoding, data};
  const std::string rec = SchemaRecord(s);
  if (!chunk_.empty()) {
    chunk_ += rec;
  } else {
    WriteRaw(rec);
  }
  schemas_.push_back(std::move(s));
  stats_.schema_count = static_cast<std::uint16_t>(schemas_.size());
  return schemas_.back().id;
}

std::uint16_t Writer::AddChannel(std::uint16_t schema_id, const std::string& topic,
                                 const std::string& message_encoding, const KeyValues& metadata) {
  Channel c{static_cast<std::uint16_t>(channels_.size()), schema_id, topic, message_encoding, metadata};
  const std::string rec = ChannelRecord(c);
  if (!chunk_.empty()) {
    chunk_ += rec;
  } else {
    WriteRaw(rec);
  }
  channels_.push_back(std::move(c));
  stats_.channel_count = static_cast<std::uint32_t>(channels_.size());
  stats_.channel_message_counts[channels_.back().id] = 0;
  return channels_.back().id;
}

void Writer::AddMetadata(const std::string& name, const KeyValues& values) {
  CloseChunk();
  Buf b;
  b.Str(name);
  b.Map(values);
  const std::string rec = Record(kMetadata, b.s);
  Buf idx;
  idx.U64(offset_);
  idx.U64(rec.size());
  idx.Str(name);
  metadata_index_.push_back(Record(kMetadataIndex, idx.s));
  WriteRaw(rec);
  ++stats_.metadata_count;
}

void Writer::Write(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time,
                   std::uint64_t publish_time, const void* data, std::size_t size) {
  if (closed_) return;
  if (channel_id >= channels_.size())
    throw InputError(path_ + ": internal: message on unknown channel " + std::to_string(channel_id));
  if (!chunk_has_messages_) {
    chunk_start_ = chunk_end_ = log_time;
    chunk_has_messages_ = true;
  }
  chunk_start_ = std::min(chunk_start_, log_time);
  chunk_end_ = std::max(chunk_end_, log_time);
  chunk_index_entries_[channel_id].emplace_back(log_time, chunk_.size());
  Buf b;
  b.U8(kMessage);
  b.U64(2 + 4 + 8 + 8 + size);
  b.U16(channel_id);
  b.U32(sequence);
  b.U64(log_time);
  b.U64(publish_time);
  chunk_ += b.s;
  chunk_.append(static_cast<const char*>(data), size);
  if (stats_.message_count == 0) {
    stats_.message_start_time = stats_.message_end_time = log_time;
  }
  stats_.message_start_time = std::min(stats_.message_start_time, log_time);
  stats_.message_end_time = std::max(stats_.message_end_time, log_time);
  ++stats_.message_count;
  ++stats_.channel_message_counts[channel_id];
  message_bytes_ += size;
  if (chunk_.size() >= options_.chunk_size) CloseChunk();
}

void Writer::CloseChunk() {
  if (chunk_.empty()) return;
  std::string compressed;
  const char* name = CompressionName(options_.compression);
  if (options_.compression == Compression::kZstd) {
    compressed.resize(ZSTD_compressBound(chunk_.size()));
    const std::size_t n = ZSTD_compress(compressed.data(), compressed.size(), chunk_.data(), chunk_.size(),
                                        options_.zstd_level);
    if (ZSTD_isError(n)) throw InputError(path_ + ": zstd: " + ZSTD_getErrorName(n));
    compressed.resize(n);
  } else if (options_.compression == Compression::kLz4) {
    compressed.resize(LZ4F_compressFrameBound(chunk_.size(), nullptr));
    const std::size_t n =
        LZ4F_compressFrame(compressed.data(), compressed.size(), chunk_.data(), chunk_.size(), nullptr);
    if (LZ4F_isError(n)) throw InputError(path_ + ": lz4: " + LZ4F_getErrorName(n));
    compressed.resize(n);
  }
  const std::string& records = options_.compression == Compression::kNone ? chunk_ : compressed;
  const std::uint64_t start = chunk_has_messages_ ? chunk_start_ : 0,
                      end = chunk_has_messages_ ? chunk_end_ : 0;
  Buf c;
  c.U64(start);
  c.U64(end);
  c.U64(chunk_.size());
  c.U32(Crc32(chunk_.data(), chunk_.size()));
  c.Str(name);
  c.U64(records.size());
  c.s += records;
  const std::string rec = Record(kChunk, c.s);
  const std::uint64_t chunk_offset = offset_;
  WriteRaw(rec);
  // One Message Index per channel in the chunk, in channel order.
  KeyValues unused;
  Buf offsets;
  const std::uint64_t index_start = offset_;
  for (const auto& [channel, entries] : chunk_index_entries_) {
    offsets.U16(channel);
    offsets.U64(offset_);
    Buf m;
    m.U16(channel);
    Buf arr;
    for (const auto& [t, off] : entries) {
      arr.U64(t);
      arr.U64(off);
    }
    m.Str(arr.s);
    WriteRaw(Record(kMessageIndex, m.s));
  }
  Buf ci;
  ci.U64(start);
  ci.U64(end);
  ci.U64(chunk_offset);
  ci.U64(rec.size());
  ci.Str(offsets.s);
  ci.U64(offset_ - index_start);
  ci.Str(name);
  ci.U64(records.size());
  ci.U64(chunk_.size());
  chunk_index_.push_back(Record(kChunkIndex, ci.s));
  ++stats_.chunk_count;
  chunk_.clear();
  chunk_index_entries_.clear();
  chunk_has_messages_ = false;
}

void Writer::Flush() {
  if (closed_) return;
  CloseChunk();
  if (std::fflush(file_) != 0) throw InputError(path_ + ": write failed (" + std::strerror(errno) + ")");
}

void Writer::Close() {
  if (closed_) return;
  CloseChunk();
  Buf de;
  de.U32(data_crc_);
  WriteRaw(Record(kDataEnd, de.s));
  // Summary: groups by opcode, then one Summary Offset per group.
  const std::uint64_t summary_start = offset_;
  std::uint32_t summary_crc = 0;
  std::string summary;
  std::vector<std::string> offsets;
  auto group = [&](std::uint8_t op, const std::vector<std::string>& recs) {
    if (recs.empty()) return;
    const std::uint64_t start = summary_start + summary.size();
    for (const std::string& r : recs) summary += r;
    Buf so;
    so.U8(op);
    so.U64(start);
    so.U64(summary_start + summary.size() - start);
    offsets.push_back(Record(kSummaryOffset, so.s));
  };
  std::vector<std::string> schemas, channels, stats;
  for (const Schema& s : schemas_) schemas.push_back(SchemaRecord(s));
  for (const Channel& c : channels_) channels.push_back(ChannelRecord(c));
  Buf st;
  st.U64(stats_.message_count);
  st.U16(stats_.schema_count);
  st.U32(stats_.channel_count);
  st.U32(stats_.attachment_count);
  st.U32(stats_.metadata_count);
  st.U32(stats_.chunk_count);
  st.U64(stats_.message_start_time);
  st.U64(stats_.message_end_time);
  Buf counts;
  for (const auto& [id, n] : stats_.channel_message_counts) {
    counts.U16(id);
    counts.U64(n);
  }
  st.Str(counts.s);
  stats.push_back(Record(kStatistics, st.s));
  group(kSchema, schemas);
  group(kChannel, channels);
  group(kStatistics, stats);
  group(kMetadataIndex, metadata_index_);
  group(kChunkIndex, chunk_index_);
  const std::uint64_t summary_offset_start = summary_start + summary.size();
  for (const std::string& o : offsets) summary += o;
  Buf footer;
  footer.U8(kFooter);
  footer.U64(8 + 8 + 4);
  footer.U64(summary_start);
  footer.U64(summary_offset_start);
  summary_crc = Crc32(summary.data(), summary.size());
  summary_crc = Crc32(footer.s.data(), footer.s.size(), summary_crc);
  footer.U32(summary_crc);
  WriteRaw(summary);
  WriteRaw(footer.s);
  WriteRaw(std::string(kMagic, 8));
  if (std::fflush(file_) != 0 || ::fsync(::fileno(file_)) != 0)
    throw InputError(path_ + ": write failed (" + std::strerror(errno) + ")");
  if (std::fclose(file_) != 0) {
    file_ = nullptr;
    throw InputError(path_ + ": write failed (" + std::strerror(errno) + ")");
  }
  file_ = nullptr;
  if (std::rename(temp_path_.c_str(), path_.c_str()) != 0) {
    throw InputError(path_ + ": cannot rename " + temp_path_ + " to it (" + std::strerror(errno) + ")");
  }
  closed_ = true;
}

// ---- Reader ----------------------------------------------------------------

ReadSummary Read(const std::string& path,
                 const std::function<void(const Message&, const ReadSummary&)>& on_message,
                 const ReaderLimits& limits) {
  FileSource src(path);
  return Parser(path, src, on_message, limits).Run();
}

ReadSummary ReadBytes(const std::string& name, const std::string& bytes,
                      const std::function<void(const Message&, const ReadSummary&)>& on_message,
                      const ReaderLimits& limits) {
  MemorySource src(bytes);
  return Parser(name, src, on_message, limits).Run();
}

bool HasMcapMagic(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char b[8] = {};
  in.read(b, 8);
  return in.gcount() == 8 && std::memcmp(b, kMagic, 8) == 0;
}

}  // namespace magnav::mcap
