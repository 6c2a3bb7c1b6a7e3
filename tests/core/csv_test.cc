// CSV reader: parameters, lookups by name, and a precise error for each kind
// of malformed file.
#include "magnav/core/csv.h"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "test_data.h"

namespace magnav {
namespace {

std::string WriteTemp(const std::string& name, const std::string& text) {
  const std::string path = testing::TempDir() + "/" + name;
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

// The message of the InputError thrown by f, or "" if none.
template <class F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Csv, ParsesParametersHeaderAndRows) {
  const CsvTable t = CsvTable::Parse(
      "# title: not a number\n# sensors (1sensor): id 0: (0, 0, 0)\n# B0_T: 2e-05, 1e-06, 4.5e-05\n"
      "t,x\n0.5,1e-3\n\n# interleaved comment\n1.5, -2\n",
      "mem.csv");
  EXPECT_EQ(t.num_rows(), 2u);
  EXPECT_EQ(t.line_of(1), 8);
  EXPECT_DOUBLE_EQ(t.number(1, t.column("x")), -2.0);
  ASSERT_TRUE(t.param_vec3("B0_T").has_value());
  EXPECT_DOUBLE_EQ(t.param_vec3("B0_T")->z(), 4.5e-05);
  EXPECT_EQ(t.params().count("sensors (1sensor)"), 0u);  // not a key: has spaces
  EXPECT_EQ(t.params().at("title"), "not a number");
  EXPECT_NE(ErrorOf([&] { t.param_vec3("title"); }).find("'title'"), std::string::npos);
}

TEST(Csv, RoundTripNumbersExactly) {
  for (double v : {0.1, 1.0 / 3.0, -2.634779887389551e-09, 1e300, 5e-324}) {
    EXPECT_EQ(*ParseNumber(FormatNumber(v)), v);
  }
  EXPECT_FALSE(ParseNumber("nan"));
  EXPECT_FALSE(ParseNumber("inf"));
  EXPECT_FALSE(ParseNumber("1.5x"));
  EXPECT_FALSE(ParseNumber(""));
  EXPECT_EQ(*ParseNumber(" +2.5 "), 2.5);
}

TEST(CsvErrors, MissingColumnNamesFileAndColumn) {
  const std::string p = WriteTemp("missing.csv", "sensor_x,sensor_y\n1,2\n");
  const std::string msg = ErrorOf([&] { ReadGradiometerFile(p); });
  EXPECT_NE(msg.find(p), std::string::npos) << msg;
  EXPECT_NE(msg.find("missing column 'sensor_z'"), std::string::npos) << msg;
}

TEST(CsvErrors, TextInNumberNamesLineAndColumn) {
  const std::string p = WriteTemp("text.csv", "# c\na,b\n1,2\n3,abc\n");
  const CsvTable t = CsvTable::Read(p);
  const std::string msg = ErrorOf([&] { t.number(1, t.column("b")); });
  EXPECT_NE(msg.find(p + ":4: column 'b': 'abc' is not a finite number"), std::string::npos) << msg;
}

TEST(CsvErrors, TruncatedLastLineIsAShortRow) {
  const std::string p = WriteTemp("trunc.csv", "a,b,c\n1,2,3\n4,5");
  const std::string msg = ErrorOf([&] { CsvTable::Read(p); });
  EXPECT_NE(msg.find(p + ":3: short row: 2 fields, header has 3 (first missing column 'c')"),
            std::string::npos) << msg;
  EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;
}

TEST(CsvErrors, TruncatedNumberInLastField) {
  const std::string p = WriteTemp("trunc2.csv", "a,b\n1,2\n4,5.0e-");
  const CsvTable t = CsvTable::Read(p);
  const std::string msg = ErrorOf([&] { t.number(1, 1); });
  EXPECT_NE(msg.find(p + ":3: column 'b': '5.0e-' is not a finite number"), std::string::npos) << msg;
}

TEST(CsvErrors, EmptyFileAndCommentsOnly) {
  const std::string p = WriteTemp("empty.csv", "");
  EXPECT_NE(ErrorOf([&] { CsvTable::Read(p); }).find(p + ": empty file: no header row"), std::string::npos);
  const std::string q = WriteTemp("comments.csv", "# a: 1\n\n");
  EXPECT_NE(ErrorOf([&] { CsvTable::Read(q); }).find("no header row"), std::string::npos);
}

TEST(CsvErrors, MissingFileDuplicateColumnEmptyFieldBinary) {
  EXPECT_NE(ErrorOf([] { CsvTable::Read("/nonexistent/x.csv"); }).find("/nonexistent/x.csv: cannot open"),
            std::string::npos);
  EXPECT_NE(ErrorOf([] { CsvTable::Parse("a,a\n", "d.csv"); }).find("d.csv:1: duplicate column 'a'"),
            std::string::npos);
  const CsvTable t = CsvTable::Parse("a,b\n1,\n", "e.csv");
  EXPECT_NE(ErrorOf([&] { t.number(0, 1); }).find("e.csv:2: column 'b': empty field"), std::string::npos);
  EXPECT_NE(ErrorOf([] { CsvTable::Parse(std::string("a,b\n1,\0\n", 8), "bin.csv"); }).find("bin.csv:2"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { CsvTable::Parse("a\n-1\n", "i.csv").integer(0, 0); }).find("not a non-negative integer"),
            std::string::npos);
}

// A 1 MiB header line of 10^5 names (found while writing fuzz/csv_entry.cc):
// the duplicate check compared every name with every earlier one and took
// minutes; now a set, well under a second.
TEST(CsvErrors, WideHeaderIsReadQuicklyAndItsDuplicateFound) {
  constexpr int kColumns = 120000;
  std::string header, row;
  for (int i = 0; i < kColumns; ++i) {
    header += (i ? ",c" : "c") + std::to_string(i);
    row += i ? ",1" : "1";
  }
  const auto start = std::chrono::steady_clock::now();
  const CsvTable t = CsvTable::Parse(header + "\n" + row + "\n", "wide.csv");
  EXPECT_EQ(t.header().size(), static_cast<std::size_t>(kColumns));
  EXPECT_NE(ErrorOf([&] { CsvTable::Parse(header + ",c119999\n" + row + ",1\n", "wide.csv"); })
                .find("wide.csv:1: duplicate column 'c119999'"),
            std::string::npos);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
}

TEST(CsvErrors, IdOutOfRangeNamesLineAndColumn) {
  const CsvTable t = CsvTable::Parse("# c\nsensor_id\n4294967295\n4294967296\n", "id.csv");
  EXPECT_EQ(t.uint32(0, 0), 4294967295u);
  EXPECT_NE(ErrorOf([&] { t.uint32(1, 0); }).find("id.csv:4: column 'sensor_id': out of range"), std::string::npos);
}

TEST(CsvErrors, BadParameterInGradiometerFile) {
  const std::string p = WriteTemp("badparam.csv", "# B0_T: 1, 2\nsensor_x\n1\n");
  const std::string msg = ErrorOf([&] { ReadGradiometerFile(p); });
  EXPECT_NE(msg.find("parameter 'B0_T': expected 3 numbers, found 2"), std::string::npos) << msg;
}

TEST(GradiometerFile, ReadsReferencePass) {
  const GradiometerFile f = ReadGradiometerFile(testing::ReferencePath("track_pass_auv_4sensor_fluxgate.csv"));
  ASSERT_EQ(f.samples.size(), 4u * 2001u);
  ASSERT_TRUE(f.B0 && f.moment_body && f.sigma_B && f.sigma_T);
  EXPECT_DOUBLE_EQ(f.B0->z(), 4.5e-05);
  EXPECT_DOUBLE_EQ(f.moment_body->x(), 2000.0);
  EXPECT_DOUBLE_EQ(*f.sigma_T, 1.4e-09);
  EXPECT_EQ(f.samples[5].sensor_id, 1u);
  EXPECT_DOUBLE_EQ(f.samples[5].t_s, 0.1);
  EXPECT_DOUBLE_EQ(f.samples[5].p_SinW.x(), -20.0);
  EXPECT_DOUBLE_EQ(f.samples[5].sigma_B, 1e-9);
}

TEST(CsvWriter, WritesReadableFile) {
  const std::string p = testing::TempDir() + "/out.csv";
  {
    CsvWriter w(p, {"a", "b"}, {{"B0_T", "1, 2, 3"}});
    w.WriteRow({FormatNumber(0.1), "x"});
    EXPECT_THROW(w.WriteRow({"1"}), InputError);
    w.Close();
  }
  const CsvTable t = CsvTable::Read(p);
  EXPECT_EQ(t.number(0, 0), 0.1);
  EXPECT_EQ(t.text(0, 1), "x");
  EXPECT_EQ(t.param_vec3("B0_T")->y(), 2.0);
  EXPECT_THROW(CsvWriter("/nonexistent/dir/o.csv", {"a"}), InputError);
}

std::vector<std::string> Names(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::string Contents(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Rows go to a temporary renamed by Close(): a writer given up part-way (an
// error: destroyed without Close) leaves neither a cut-off file nor its
// temporary, and an existing file keeps its contents until Close().
TEST(CsvWriter, OutputIsCompleteOrAbsent) {
  const std::string dir = testing::TempDir();
  const std::string p = dir + "/out.csv";
  {
    CsvWriter w(p, {"a"});
    w.WriteRow({"1"});
    EXPECT_FALSE(std::filesystem::exists(p));
  }
  EXPECT_TRUE(Names(dir).empty());
  std::ofstream(p) << "old\n";
  {
    CsvWriter w(p, {"a"});
    w.WriteRow({"1"});
    EXPECT_EQ(Contents(p), "old\n");
  }
  EXPECT_EQ(Contents(p), "old\n");
  {
    CsvWriter w(p, {"a"});
    w.WriteRow({"1"});
    w.Close();
  }
  EXPECT_EQ(Contents(p), "a\n1\n");
  EXPECT_EQ(Names(dir), std::vector<std::string>{"out.csv"});
}

// SIGTERM while a writer is open (a program without its own handler, as the
// offline commands): the temporary is removed, an existing output untouched,
// and the process still dies of the signal.
TEST(CsvWriter, SigtermLeavesNoTemporary) {
  const std::string dir = testing::TempDir();
  const std::string p = dir + "/out.csv";
  std::ofstream(p) << "old\n";
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    CsvWriter w(p, {"a"});
    w.WriteRow({"1"});
    ::kill(::getpid(), SIGTERM);
    ::_exit(0);  // not reached
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM);
  EXPECT_EQ(Names(dir), std::vector<std::string>{"out.csv"});
  EXPECT_EQ(Contents(p), "old\n");
}

// Output equal to an input, however spelled, is refused.
TEST(CsvWriter, RefusesOutputOverInput) {
  const std::string dir = testing::TempDir();
  const std::string in = dir + "/in.csv";
  std::ofstream(in) << "a\n1\n";
  std::filesystem::create_hard_link(in, dir + "/hard.csv");
  std::filesystem::create_symlink(in, dir + "/soft.csv");
  for (const std::string& out : {in, dir + "/./in.csv", dir + "/hard.csv", dir + "/soft.csv"}) {
    EXPECT_NE(ErrorOf([&] { RefuseOutputOverInput(out, {"", in}); }).find("are the same file"), std::string::npos)
        << out;
  }
  EXPECT_EQ(ErrorOf([&] { RefuseOutputOverInput(dir + "/new.csv", {in}); }), "");
  EXPECT_EQ(ErrorOf([&] { RefuseOutputOverInput("", {in}); }), "");
}

// Reading is bounded: a file without newlines fails after 1 MiB, naming the
// limit; a BOM and CRLF line ends are read as a plain file.
TEST(CsvErrors, LongLineBomAndCrlf) {
  const std::string msg = ErrorOf([] { CsvTable::Read("/dev/zero"); });
  EXPECT_NE(msg.find("/dev/zero:1: line longer than 1 MiB (no newline)"), std::string::npos) << msg;
  const std::string p = WriteTemp("long.csv", "a\n" + std::string(CsvTable::kMaxLineBytes + 10, '1'));
  EXPECT_NE(ErrorOf([&] { CsvTable::Read(p); }).find(p + ":2: line longer than"), std::string::npos);
  const std::string q = WriteTemp("bom.csv", "\xEF\xBB\xBF# k: 1\r\nt,b\r\n1,2\r\n");
  const CsvTable t = CsvTable::Read(q);
  EXPECT_EQ(t.header(), (std::vector<std::string>{"t", "b"}));
  EXPECT_EQ(t.number(0, t.column("b")), 2.0);
  EXPECT_EQ(*t.param_number("k"), 1.0);
  EXPECT_NE(ErrorOf([&] { CsvTable::Read(WriteTemp("h.csv", "# c\nt,b\n\n")); }).find(":2: no data rows"),
            std::string::npos);
}

}  // namespace
}  // namespace magnav
