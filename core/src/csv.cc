#include "magnav/core/csv.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <unordered_set>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include "magnav/core/error.h"

namespace magnav {
namespace {

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::vector<std::string> SplitFields(std::string_view line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    const std::string_view f = line.substr(start, comma == std::string_view::npos ? line.npos : comma - start);
    out.emplace_back(Trim(f));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return out;
}

bool IsParamKey(std::string_view k) {
  if (k.empty()) return false;
  for (char c : k) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  }
  return true;
}

std::string Quote(std::string_view s) {
  constexpr std::size_t kMax = 40;
  std::string q = "'";
  q += s.size() > kMax ? std::string(s.substr(0, kMax)) + "..." : std::string(s);
  q += "'";
  return q;
}

}  // namespace

std::optional<double> ParseNumber(std::string_view text) {
  text = Trim(text);
  if (text.empty()) return std::nullopt;
  if (text.front() == '+') text.remove_prefix(1);
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<std::vector<double>> ParseNumberList(std::string_view text) {
  std::vector<double> out;
  for (const std::string& f : SplitFields(text)) {
    const auto v = ParseNumber(f);
    if (!v) return std::nullopt;
    out.push_back(*v);
  }
  return out;
}

std::string FormatVec3(const Eigen::Vector3d& v) {
  return FormatNumber(v.x()) + ", " + FormatNumber(v.y()) + ", " + FormatNumber(v.z());
}

std::string FormatNumber(double value) {
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), value);
  if (ec != std::errc()) return "nan";
  return std::string(buf, ptr);
}

// Turns lines into a CsvTable one at a time (Read feeds them as chunks of
// the file arrive, Parse from text in memory).
class CsvTable::Parser {
 public:
  explicit Parser(const std::string& source) { t_.source_ = source; }
  // The fields of a file of `bytes` take at most that much: reserved at
  // once, the buffer never grows by doubling (a 289 MB file peaked at 634 MB).
  void Reserve(std::size_t bytes) { t_.fields_.reserve(std::min(bytes, kMaxFieldBytes)); }

  // One line without its '\n'; `unterminated`: the file's last line, with no
  // newline after it.
  void Line(std::string_view line, bool unterminated) {
    ++line_no_;
    // A UTF-8 byte-order mark (as some editors and spreadsheets write) is
    // not part of the first column's name.
    if (line_no_ == 1 && line.substr(0, 3) == "\xEF\xBB\xBF") line.remove_prefix(3);
    const std::string_view trimmed = Trim(line);
    if (trimmed.empty()) return;
    if (trimmed.front() == '#') {
      std::string_view body = Trim(trimmed.substr(1));
      const std::size_t colon = body.find(':');
      if (colon != std::string_view::npos) {
        const std::string_view key = Trim(body.substr(0, colon));
        if (IsParamKey(key)) t_.params_[std::string(key)] = std::string(Trim(body.substr(colon + 1)));
      }
      return;
    }
    if (trimmed.find('\0') != std::string_view::npos) {
      throw InputError(Where() + "binary data (NUL byte) in a CSV file");
    }
    if (header_line_ == 0) return Header(trimmed);
    // Fields straight into the table's buffer; counted, then checked.
    const std::size_t columns = t_.header_.size();
    std::size_t n = 0;
    for (std::size_t start = 0;; ++n) {
      const std::size_t comma = trimmed.find(',', start);
      const std::string_view f = Trim(trimmed.substr(start, comma == std::string_view::npos ? trimmed.npos
                                                                                            : comma - start));
      if (n < columns) {
        if (t_.fields_.size() + f.size() > kMaxFieldBytes) {
          throw InputError(Where() + "more than 4 GiB of fields: the file is too large to read whole");
        }
        t_.fields_.append(f);
        t_.ends_.push_back(static_cast<std::uint32_t>(t_.fields_.size()));
      }
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    ++n;
    if (n != columns) {
      std::string what = n < columns ? "short row" : "long row";
      std::string msg = Where() + what + ": " + std::to_string(n) + " fields, header has " + std::to_string(columns);
      if (n < columns) msg += " (first missing column " + Quote(t_.header_[n]) + ")";
      if (unterminated) msg += "; the file looks truncated (no newline at end)";
      throw InputError(msg);
    }
    t_.lines_.push_back(line_no_);
  }

  CsvTable Finish() {
    if (header_line_ == 0) {
      throw InputError(t_.source_ + ": empty file: no header row" +
                       std::string(line_no_ > 0 ? " (only comments or blank lines)" : ""));
    }
    if (t_.lines_.empty()) {
      throw InputError(t_.source_ + ":" + std::to_string(header_line_) +
                       ": no data rows (the file ends after its header)");
    }
    if (t_.fields_.capacity() > 2 * t_.fields_.size() + 4096) t_.fields_.shrink_to_fit();
    t_.ends_.shrink_to_fit();
    t_.lines_.shrink_to_fit();
    return std::move(t_);
  }

  int line_no() const { return line_no_; }

 private:
  std::string Where() const { return t_.source_ + ":" + std::to_string(line_no_) + ": "; }

  void Header(std::string_view line) {
    std::vector<std::string> fields = SplitFields(line);
    // A set, not a pairwise comparison: a header line of 1 MiB holds 10^5
    // names, and comparing each with every earlier one took minutes.
    std::unordered_set<std::string_view> names;
    names.reserve(fields.size());
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (fields[i].empty()) throw InputError(Where() + "header column " + std::to_string(i + 1) + " has no name");
      if (!names.insert(fields[i]).second) {
        throw InputError(Where() + "duplicate column " + Quote(fields[i]) + " in header");
      }
    }
    t_.header_ = std::move(fields);
    header_line_ = line_no_;
  }

  CsvTable t_;
  int line_no_ = 0;
  int header_line_ = 0;
};

CsvTable CsvTable::Read(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) throw InputError(path + ": is a directory, not a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open file for reading");
  // Read in chunks and parse each complete line at once, never holding a line
  // longer than kMaxLineBytes: a device or a binary file without newlines
  // (/dev/zero) fails after 1 MiB instead of growing memory until the machine
  // gives out, and a large file is not held twice (text and fields).
  Parser parser(path);
  if (::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode)) parser.Reserve(static_cast<std::size_t>(st.st_size));
  std::string pending;  // the unfinished line
  std::vector<char> chunk(1 << 16);
  while (in) {
    in.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    const std::size_t n = static_cast<std::size_t>(in.gcount());
    if (n == 0) break;
    std::string_view data(chunk.data(), n);
    for (std::size_t nl; (nl = data.find('\n')) != std::string_view::npos; data.remove_prefix(nl + 1)) {
      if (pending.empty()) {
        parser.Line(data.substr(0, nl), false);
      } else {
        pending.append(data.substr(0, nl));
        parser.Line(pending, false);
        pending.clear();
      }
    }
    pending.append(data);
    if (pending.size() > kMaxLineBytes) {
      throw InputError(path + ":" + std::to_string(parser.line_no() + 1) + ": line longer than " +
                       std::to_string(kMaxLineBytes >> 20) + " MiB (no newline): not a CSV file");
    }
  }
  if (in.bad()) throw InputError(path + ": read error");
  if (!pending.empty()) parser.Line(pending, true);
  return parser.Finish();
}

CsvTable CsvTable::Parse(std::string_view text, const std::string& source) {
  Parser parser(source);
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    if (nl == std::string_view::npos) {
      parser.Line(text, true);
      break;
    }
    parser.Line(text.substr(0, nl), false);
    text.remove_prefix(nl + 1);
  }
  return parser.Finish();
}

bool CsvTable::has_column(std::string_view name) const { return find_column(name).has_value(); }

std::optional<std::size_t> CsvTable::find_column(std::string_view name) const {
  for (std::size_t i = 0; i < header_.size(); ++i) {
    if (header_[i] == name) return i;
  }
  return std::nullopt;
}

std::size_t CsvTable::column(std::string_view name) const {
  if (auto c = find_column(name)) return *c;
  std::string cols;
  for (std::size_t i = 0; i < header_.size(); ++i) cols += (i ? "," : "") + header_[i];
  throw InputError(source_ + ": missing column " + Quote(name) + " (header has: " + cols + ")");
}

double CsvTable::number(std::size_t row, std::size_t col) const {
  const std::string_view f = text(row, col);
  if (auto v = ParseNumber(f)) return *v;
  throw InputError(source_ + ":" + std::to_string(lines_[row]) + ": column " + Quote(header_[col]) + ": " +
                   (f.empty() ? std::string("empty field") : Quote(f) + " is not a finite number"));
}

long long CsvTable::integer(std::size_t row, std::size_t col) const {
  const std::string_view f = text(row, col);
  long long v = 0;
  const auto [ptr, ec] = std::from_chars(f.data(), f.data() + f.size(), v);
  if (ec == std::errc() && ptr == f.data() + f.size() && v >= 0) return v;
  // Accept integral floats such as "3.0".
  if (auto d = ParseNumber(f); d && *d >= 0 && *d == std::floor(*d) && *d < 9e15) return static_cast<long long>(*d);
  throw InputError(source_ + ":" + std::to_string(lines_[row]) + ": column " + Quote(header_[col]) + ": " +
                   (f.empty() ? std::string("empty field") : Quote(f) + " is not a non-negative integer"));
}

std::uint32_t CsvTable::uint32(std::size_t row, std::size_t col) const {
  const long long v = integer(row, col);
  if (v > 0xFFFFFFFFLL) {
    throw InputError(source_ + ":" + std::to_string(lines_[row]) + ": column " + Quote(header_[col]) +
                     ": out of range");
  }
  return static_cast<std::uint32_t>(v);
}

std::vector<double> CsvTable::param_numbers(const std::string& key, std::size_t expected_count) const {
  const auto it = params_.find(key);
  if (it == params_.end()) throw InputError(source_ + ": missing parameter line '# " + key + ": ...'");
  auto v = ParseNumberList(it->second);
  if (!v) throw InputError(source_ + ": parameter '" + key + "': " + Quote(it->second) + " is not a list of numbers");
  if (expected_count > 0 && v->size() != expected_count) {
    throw InputError(source_ + ": parameter '" + key + "': expected " + std::to_string(expected_count) +
                     " numbers, found " + std::to_string(v->size()));
  }
  return *v;
}

std::optional<Eigen::Vector3d> CsvTable::param_vec3(const std::string& key) const {
  if (!has_param(key)) return std::nullopt;
  const auto v = param_numbers(key, 3);
  return Eigen::Vector3d(v[0], v[1], v[2]);
}

std::optional<double> CsvTable::param_number(const std::string& key) const {
  if (!has_param(key)) return std::nullopt;
  return param_numbers(key, 1)[0];
}

namespace {

// Temporary files of the CsvWriters still open, removed if the process is
// stopped by SIGINT/SIGTERM before they are renamed. Fixed slots, so that the
// handler touches no allocator (it only calls unlink, signal and raise).
constexpr int kMaxTempFiles = 8;
constexpr std::size_t kMaxTempPath = 4096;
char g_temp_paths[kMaxTempFiles][kMaxTempPath];
volatile std::sig_atomic_t g_temp_used[kMaxTempFiles];
std::mutex g_temp_mutex;

extern "C" void RemoveTempFilesAndDie(int sig) {
  for (int i = 0; i < kMaxTempFiles; ++i) {
    if (g_temp_used[i]) ::unlink(g_temp_paths[i]);
  }
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

// Registers a temporary file; installs the handler for SIGINT/SIGTERM unless
// the program has its own (magnav record stops cleanly on them and closes).
int RegisterTempFile(const std::string& path) {
  std::lock_guard<std::mutex> lock(g_temp_mutex);
  static const bool installed = [] {
    for (int sig : {SIGINT, SIGTERM}) {
      struct sigaction old {};
      if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_DFL) std::signal(sig, RemoveTempFilesAndDie);
    }
    return true;
  }();
  (void)installed;
  if (path.size() >= kMaxTempPath) return -1;
  for (int i = 0; i < kMaxTempFiles; ++i) {
    if (!g_temp_used[i]) {
      std::memcpy(g_temp_paths[i], path.c_str(), path.size() + 1);
      g_temp_used[i] = 1;
      return i;
    }
  }
  return -1;
}

void UnregisterTempFile(int slot) {
  if (slot < 0) return;
  std::lock_guard<std::mutex> lock(g_temp_mutex);
  g_temp_used[slot] = 0;
}

}  // namespace

void RefuseOutputOverInput(const std::string& output, const std::vector<std::string>& inputs) {
  namespace fs = std::filesystem;
  if (output.empty()) return;
  std::error_code ec;
  const fs::path out = fs::weakly_canonical(output, ec);
  for (const std::string& input : inputs) {
    if (input.empty()) continue;
    std::error_code ec1, ec2;
    const bool same = fs::equivalent(output, input, ec1) ||
                      (!ec && fs::weakly_canonical(input, ec2) == out && !ec2);
    if (same) {
      throw InputError("output " + output + " and input " + input +
                       " are the same file: refusing to overwrite an input (give another output path)");
    }
  }
}

struct CsvWriter::Impl {
  std::ofstream out;
  std::string temp_path;
  int slot = -1;
  bool renamed = false;
};

CsvWriter::CsvWriter(const std::string& path, std::vector<std::string> header,
                     const std::vector<std::pair<std::string, std::string>>& params)
    : path_(path), num_columns_(header.size()), impl_(new Impl) {
  // A temporary in the same directory (so that rename is atomic), created
  // exclusively with the permissions a plain open would give.
  for (int attempt = 0;; ++attempt) {
    impl_->temp_path = path + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(attempt);
    const int fd = ::open(impl_->temp_path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) {
      ::close(fd);
      break;
    }
    if (errno != EEXIST || attempt >= 100) {
      const std::string why = std::strerror(errno);
      delete impl_;
      throw InputError(path + ": cannot open file for writing (" + why + ")");
    }
  }
  impl_->slot = RegisterTempFile(impl_->temp_path);
  impl_->out.open(impl_->temp_path, std::ios::binary | std::ios::trunc);
  if (!impl_->out) {
    ::unlink(impl_->temp_path.c_str());
    UnregisterTempFile(impl_->slot);
    delete impl_;
    throw InputError(path + ": cannot open file for writing");
  }
  for (const auto& [k, v] : params) impl_->out << "# " << k << ": " << v << '\n';
  for (std::size_t i = 0; i < header.size(); ++i) impl_->out << (i ? "," : "") << header[i];
  impl_->out << '\n';
}

CsvWriter::~CsvWriter() {
  if (!impl_->renamed) {
    impl_->out.close();
    ::unlink(impl_->temp_path.c_str());
  }
  UnregisterTempFile(impl_->slot);
  delete impl_;
}

void CsvWriter::AddComment(const std::string& text) { impl_->out << "# " << text << '\n'; }

void CsvWriter::WriteRow(const std::vector<std::string>& fields) {
  if (fields.size() != num_columns_) {
    throw InputError(path_ + ": internal: row with " + std::to_string(fields.size()) + " fields for " +
                     std::to_string(num_columns_) + " columns");
  }
  for (std::size_t i = 0; i < fields.size(); ++i) impl_->out << (i ? "," : "") << fields[i];
  impl_->out << '\n';
}

void CsvWriter::Flush() {
  impl_->out.flush();
  if (!impl_->out) throw InputError(path_ + ": write failed");
}

void CsvWriter::Close() {
  if (impl_->renamed) return;
  impl_->out.flush();
  if (!impl_->out) throw InputError(path_ + ": write failed");
  impl_->out.close();
  if (!impl_->out) throw InputError(path_ + ": write failed");
  if (std::rename(impl_->temp_path.c_str(), path_.c_str()) != 0) {
    throw InputError(path_ + ": cannot rename " + impl_->temp_path + " to it (" + std::strerror(errno) + ")");
  }
  impl_->renamed = true;
}

}  // namespace magnav
