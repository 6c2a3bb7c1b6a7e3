// CSV input/output shared by every offline command.
//
// Format: optional '#' comment lines (anywhere before or between rows), exactly
// one header row, then comma-separated data rows. A comment of the form
// "# key: value" with key made of [A-Za-z0-9_] is a parameter (the reference
// files carry "# B0_T: 2e-05, 1e-06, 4.5e-05" and the like). Columns are found
// by header name, never by position. Every error names the file and, where it
// applies, the line (1-based, as an editor shows it) and the column.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace magnav {

class CsvTable {
 public:
  // Longest line Read accepts (1 MiB): a file without newlines (a device such
  // as /dev/zero, a binary file) is refused after that much, not read whole.
  static constexpr std::size_t kMaxLineBytes = std::size_t{1} << 20;
  // Most text of all fields together (4 GiB - 1: offsets are 32-bit).
  static constexpr std::size_t kMaxFieldBytes = 0xFFFFFFFFu;

  // Reads a file; throws InputError (missing file, a directory, empty file, no
  // header, no data row after the header, duplicate column names, a row with
  // the wrong number of fields, a line longer than kMaxLineBytes, more than
  // kMaxFieldBytes of fields). A UTF-8 byte-order mark is skipped and CRLF
  // line ends are read as LF. Lines are parsed as they are read: memory is
  // the fields' text plus 4 bytes per field and per row (about 1.3x the
  // file), never the file twice.
  static CsvTable Read(const std::string& path);
  // Parses text already in memory; `source` names it in errors.
  static CsvTable Parse(std::string_view text, const std::string& source);

  const std::string& source() const { return source_; }
  const std::vector<std::string>& header() const { return header_; }
  std::size_t num_rows() const { return lines_.size(); }
  // 1-based line number of a data row in the source.
  int line_of(std::size_t row) const { return lines_[row]; }

  bool has_column(std::string_view name) const;
  // Index of a column; throws "FILE: missing column 'NAME' (header has: ...)".
  std::size_t column(std::string_view name) const;
  // Index of the first present column among names, or nullopt.
  std::optional<std::size_t> find_column(std::string_view name) const;

  // The field's text (trimmed); valid as long as the table.
  std::string_view text(std::size_t row, std::size_t col) const {
    const std::size_t k = row * header_.size() + col;
    return std::string_view(fields_).substr(ends_[k], ends_[k + 1] - ends_[k]);
  }
  // The field as a finite double; throws "FILE:LINE: column 'NAME': 'abc' is not a number".
  double number(std::size_t row, std::size_t col) const;
  // The field as a non-negative integer.
  long long integer(std::size_t row, std::size_t col) const;
  // The field as an unsigned 32-bit id (e.g. sensor_id); throws
  // "FILE:LINE: column 'NAME': out of range" above 4294967295.
  std::uint32_t uint32(std::size_t row, std::size_t col) const;

  // "# key: value" parameters.
  const std::map<std::string, std::string>& params() const { return params_; }
  bool has_param(const std::string& key) const { return params_.count(key) != 0; }
  // A parameter as comma-separated numbers; throws naming the key if a value
  // is not a number or the count differs from `expected_count` (when > 0).
  std::vector<double> param_numbers(const std::string& key, std::size_t expected_count = 0) const;
  std::optional<Eigen::Vector3d> param_vec3(const std::string& key) const;
  std::optional<double> param_number(const std::string& key) const;

 private:
  class Parser;
  std::string source_;
  std::vector<std::string> header_;
  // Every data field's text, row after row; field k (row r, column c: k =
  // r·columns + c) is fields_[ends_[k], ends_[k+1]).
  std::string fields_;
  std::vector<std::uint32_t> ends_{0};
  std::vector<int> lines_;  // per data row
  std::map<std::string, std::string> params_;
};

// Parses a finite double from the whole of `text` (surrounding spaces allowed).
std::optional<double> ParseNumber(std::string_view text);
// Parses "a,b,c" into numbers; nullopt if any is not a number.
std::optional<std::vector<double>> ParseNumberList(std::string_view text);

// Formats a double as the shortest string that reads back to the same value.
std::string FormatNumber(double value);
// "x, y, z" with FormatNumber (as the `# key: X, Y, Z` parameters are written;
// ParseNumberList reads it back).
std::string FormatVec3(const Eigen::Vector3d& v);

// Throws InputError if `output` is the same file as one of `inputs` (after
// resolving links and "..", or a hard link to it): every command that writes
// a file calls it first, so that --output equal to --input is refused.
void RefuseOutputOverInput(const std::string& output, const std::vector<std::string>& inputs);

// Writes a CSV file: parameter comments, header, rows. Fields are written as
// given (numbers through FormatNumber). Safe for the file it replaces: rows go
// to a temporary "PATH.tmp-PID-N" in the same directory, renamed to PATH by
// Close(); a writer destroyed without Close() (an error part-way) removes it,
// and so does SIGINT/SIGTERM in a program without its own handler for them.
// So an output file is either complete or absent, and an existing one is
// untouched until the new one is complete. Throws InputError if the file
// cannot be created or a row has the wrong number of fields.
class CsvWriter {
 public:
  CsvWriter(const std::string& path, std::vector<std::string> header,
            const std::vector<std::pair<std::string, std::string>>& params = {});
  ~CsvWriter();
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;

  void AddComment(const std::string& text);
  void WriteRow(const std::vector<std::string>& fields);
  // Hands the rows written so far to the operating system (the temporary
  // then holds them, whole, if the process is killed); throws if the write
  // failed. For long-running writers (`magnav record`).
  void Flush();
  // Flushes, closes and renames the temporary to the path; throws if the
  // write failed (disk full, ...).
  void Close();

 private:
  std::string path_;
  std::size_t num_columns_;
  struct Impl;
  Impl* impl_;
};

}  // namespace magnav
