#include "magnav/core/checkpoint.h"

#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include <fcntl.h>
#include <unistd.h>

namespace magnav {

static_assert(std::endian::native == std::endian::little, "checkpoints are written little-endian");

namespace {
constexpr std::size_t kHeader = 8 + 4 + 8;
}  // namespace

void StateWriter::U32(std::uint32_t v) { bytes_.append(reinterpret_cast<const char*>(&v), sizeof v); }
void StateWriter::U64(std::uint64_t v) { bytes_.append(reinterpret_cast<const char*>(&v), sizeof v); }
void StateWriter::F64(double v) { U64(std::bit_cast<std::uint64_t>(v)); }

void StateWriter::Matrix(const Eigen::MatrixXd& m) {
  U64(static_cast<std::uint64_t>(m.rows()));
  U64(static_cast<std::uint64_t>(m.cols()));
  for (Eigen::Index i = 0; i < m.size(); ++i) F64(m.data()[i]);
}

void StateWriter::Bytes(std::string_view s) {
  U64(s.size());
  bytes_.append(s);
}

std::string_view StateReader::Take(std::size_t n) {
  if (bytes_.size() - pos_ < n) {
    throw CheckpointError("truncated: " + std::to_string(n) + " byte(s) wanted at payload offset " +
                          std::to_string(pos_) + " of " + std::to_string(bytes_.size()));
  }
  const std::string_view s = bytes_.substr(pos_, n);
  pos_ += n;
  return s;
}

std::uint8_t StateReader::U8() { return static_cast<std::uint8_t>(Take(1)[0]); }

std::uint32_t StateReader::U32() {
  std::uint32_t v;
  std::memcpy(&v, Take(4).data(), 4);
  return v;
}

std::uint64_t StateReader::U64() {
  std::uint64_t v;
  std::memcpy(&v, Take(8).data(), 8);
  return v;
}

double StateReader::F64() { return std::bit_cast<double>(U64()); }

std::size_t StateReader::Count(std::size_t max) {
  const std::uint64_t n = U64();
  if (n > max) throw CheckpointError("corrupt: a count of " + std::to_string(n) + " (at most " + std::to_string(max) + ")");
  return static_cast<std::size_t>(n);
}

Eigen::MatrixXd StateReader::Matrix(std::size_t max_rows, std::size_t max_cols) {
  const std::size_t r = Count(max_rows), c = Count(max_cols);
  Eigen::MatrixXd m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c));
  for (Eigen::Index i = 0; i < m.size(); ++i) m.data()[i] = F64();
  return m;
}

std::string StateReader::Bytes(std::size_t max) {
  const std::size_t n = Count(max);
  return std::string(Take(n));
}

std::uint64_t Fnv1a64(std::string_view bytes) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : bytes) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  return h;
}

std::string EncodeCheckpoint(const CheckpointKind& kind, std::string_view payload) {
  if (kind.magic.size() != 8) throw std::logic_error("EncodeCheckpoint: the magic must be 8 bytes");
  StateWriter w;
  std::string out(kind.magic);
  w.U32(kind.version);
  w.U64(payload.size());
  out += w.bytes();
  out += payload;
  StateWriter sum;
  sum.U64(Fnv1a64(out));
  return out + sum.bytes();
}

std::string DecodeCheckpoint(const CheckpointKind& kind, std::string_view file) {
  if (file.size() < kind.magic.size() || file.substr(0, kind.magic.size()) != kind.magic) {
    throw CheckpointError("not a " + std::string(kind.program) + " checkpoint (no " + std::string(kind.magic) +
                          " magic)");
  }
  if (file.size() < kHeader + 8) {
    throw CheckpointError("truncated: " + std::to_string(file.size()) + " bytes, shorter than a header and checksum");
  }
  StateReader r(file.substr(8, 12));
  const std::uint32_t version = r.U32();
  const std::uint64_t length = r.U64();
  if (version != kind.version) {
    throw CheckpointError("format version " + std::to_string(version) + ", this program reads version " +
                          std::to_string(kind.version));
  }
  if (length != file.size() - kHeader - 8) {
    throw CheckpointError((length > file.size() - kHeader - 8 ? "truncated: " : "corrupt: ") +
                          std::string("the header says ") + std::to_string(length) + " payload bytes, the file has " +
                          std::to_string(file.size() - kHeader - 8));
  }
  StateReader s(file.substr(file.size() - 8));
  if (s.U64() != Fnv1a64(file.substr(0, file.size() - 8))) {
    throw CheckpointError("corrupt: checksum mismatch");
  }
  return std::string(file.substr(kHeader, length));
}

namespace {
std::string Errno(const std::string& what) { return what + ": " + std::strerror(errno); }

void WriteAll(int fd, std::string_view bytes, const std::string& path) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(Errno("writing " + path));
    }
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
}
}  // namespace

void WriteFileAtomically(const std::string& path, std::string_view bytes) {
  const std::size_t slash = path.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error(Errno("creating " + tmp));
  try {
    WriteAll(fd, bytes, tmp);
    if (::fsync(fd) != 0) throw std::runtime_error(Errno("fsync " + tmp));
  } catch (...) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw;
  }
  if (::close(fd) != 0) {
    ::unlink(tmp.c_str());
    throw std::runtime_error(Errno("closing " + tmp));
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = Errno("renaming " + tmp + " to " + path);
    ::unlink(tmp.c_str());
    throw std::runtime_error(why);
  }
  // The rename itself is durable once the directory is.
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

bool ReadWholeFile(const std::string& path, std::string* bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    if (::access(path.c_str(), F_OK) != 0 && errno == ENOENT) return false;
    throw std::runtime_error(Errno("opening " + path));
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw std::runtime_error("reading " + path + " failed");
  *bytes = ss.str();
  return true;
}

}  // namespace magnav
