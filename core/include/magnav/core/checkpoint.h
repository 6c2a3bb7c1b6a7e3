// Checkpoint files: a service's state in a small binary file that survives a
// crash (docs/RELIABILITY.md "Delivery, crash and restart"). The one
// container both magnav-localizer (localizer/checkpoint.h) and magnav-tracker
// (tracker/checkpoint.h) write; each gives its own magic and version and
// writes its own payload with StateWriter.
//
// File format (all integers and doubles little-endian; a double is its 8
// IEEE-754 bytes, so it round-trips bit for bit):
//
//   offset  size  field
//   0       8     magic (the writer's, e.g. "MAGNAVLC")
//   8       4     u32 format version (the writer's)
//   12      8     u64 payload length N
//   20      N     payload
//   20+N    8     u64 checksum: FNV-1a 64 over bytes 0 .. 20+N−1
//
// Anything else — a short file, trailing bytes, another magic, version or
// checksum — is refused by DecodeCheckpoint with a CheckpointError saying
// which. Not thread-safe.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

#include <Eigen/Core>

namespace magnav {

// A checkpoint that cannot be used: corrupt, truncated, of another version
// or of another configuration. what() says which.
class CheckpointError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Appends fields to a payload.
class StateWriter {
 public:
  void U8(std::uint8_t v) { bytes_.push_back(static_cast<char>(v)); }
  void U32(std::uint32_t v);
  void U64(std::uint64_t v);
  void I64(std::int64_t v) { U64(static_cast<std::uint64_t>(v)); }
  void F64(double v);
  // Rows, columns, then the elements column by column.
  void Matrix(const Eigen::MatrixXd& m);
  void Bytes(std::string_view s);  // length, then the bytes
  const std::string& bytes() const { return bytes_; }

 private:
  std::string bytes_;
};

// Reads them back; throws CheckpointError("truncated ...") past the end.
class StateReader {
 public:
  explicit StateReader(std::string_view bytes) : bytes_(bytes) {}
  std::uint8_t U8();
  std::uint32_t U32();
  std::uint64_t U64();
  std::int64_t I64() { return static_cast<std::int64_t>(U64()); }
  double F64();
  // A count that must be at most `max` (a corrupt length does not allocate).
  std::size_t Count(std::size_t max);
  Eigen::MatrixXd Matrix(std::size_t max_rows, std::size_t max_cols);
  std::string Bytes(std::size_t max);
  bool at_end() const { return pos_ == bytes_.size(); }

 private:
  std::string_view Take(std::size_t n);
  std::string_view bytes_;
  std::size_t pos_ = 0;
};

// FNV-1a 64-bit.
std::uint64_t Fnv1a64(std::string_view bytes);

// Which checkpoint: its 8-byte magic, its format version, and the program
// named in refusals ("magnav-localizer").
struct CheckpointKind {
  std::string_view magic;  // exactly 8 bytes
  std::uint32_t version = 1;
  std::string_view program;
};
// Header + payload + checksum (the format above).
std::string EncodeCheckpoint(const CheckpointKind& kind, std::string_view payload);
// The payload; throws CheckpointError if the file is not a checkpoint of
// this kind and version.
std::string DecodeCheckpoint(const CheckpointKind& kind, std::string_view file);

// Writes `bytes` to `path` atomically: to a temporary file in the same
// directory, fsync'd, renamed over `path`, then the directory fsync'd. A
// crash leaves the old file or the new one, never a part. Throws
// std::runtime_error with the reason on failure (the old file stays).
void WriteFileAtomically(const std::string& path, std::string_view bytes);
// False if the file does not exist; throws std::runtime_error if it cannot be read.
bool ReadWholeFile(const std::string& path, std::string* bytes);

}  // namespace magnav
