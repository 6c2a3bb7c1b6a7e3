#include "gnuplot.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "magnav/core/csv.h"
#include "magnav/core/error.h"

extern char** environ;

namespace magnav::tools {

namespace fs = std::filesystem;

std::string PaletteColour(int i) {
  return std::string("lc rgb '") + kPalette[((i % kPaletteSize) + kPaletteSize) % kPaletteSize] + "'";
}

std::string PictureFormatOf(const std::string& output) {
  for (const char* f : {"svg", "png", "pdf"}) {
    if (output.ends_with(std::string(".") + f)) return f;
  }
  return "";
}

GnuplotFigure::GnuplotFigure(const std::string& output, int width_px, int height_px, const std::string& format)
    : output_(output), format_(format), width_px_(width_px), height_px_(height_px) {
  const std::string ending = PictureFormatOf(output);
  if (format_.empty()) {
    if (ending.empty()) throw InputError("--output: '" + output + "': a picture ends in .svg, .png or .pdf (or give --format)");
    format_ = ending;
  } else if (format_ != "svg" && format_ != "png" && format_ != "pdf") {
    throw InputError("--format: expected svg, png or pdf, got '" + format_ + "'");
  } else if (!ending.empty() && ending != format_) {
    throw InputError("--format " + format_ + " disagrees with the output '" + output + "'");
  }
  std::string tmpl = (fs::temp_directory_path() / "magnav-plot-XXXXXX").string();
  if (mkdtemp(tmpl.data()) == nullptr) throw InputError("cannot create a temporary directory for gnuplot");
  dir_ = tmpl;
}

GnuplotFigure::~GnuplotFigure() {
  std::error_code ec;
  fs::remove_all(dir_, ec);
}

std::string GnuplotFigure::Data(const std::string& name, const std::vector<std::vector<double>>& rows) {
  const std::string path = dir_ + "/" + name + ".dat";
  std::ofstream out(path);
  for (const auto& r : rows) {
    for (std::size_t i = 0; i < r.size(); ++i) out << (i ? " " : "") << FormatNumber(r[i]);
    out << '\n';
  }
  if (!out) throw InputError("cannot write gnuplot data to " + path);
  return "'" + path + "'";
}

void GnuplotFigure::Script(const std::string& lines) { script_ += lines + "\n"; }

void GnuplotFigure::Render() {
  const fs::path final_path = fs::absolute(output_);
  const std::string picture = dir_ + "/figure." + format_;
  std::ostringstream head;
  if (format_ == "svg") {
    head << "set terminal svg size " << width_px_ << "," << height_px_ << " dynamic noenhanced font 'sans,12'\n";
  } else if (format_ == "png") {
    head << "set terminal pngcairo size " << width_px_ << "," << height_px_ << " noenhanced font 'sans,11'\n";
  } else {
    head << "set terminal pdfcairo size " << width_px_ / 100.0 << "in," << height_px_ / 100.0
         << "in noenhanced font 'sans,11'\n";
  }
  head << "set output '" << picture << "'\n";
  for (int i = 0; i < kPaletteSize; ++i) head << "set linetype " << i + 1 << " lc rgb '" << kPalette[i] << "' lw 1\n";
  head << "set linetype cycle " << kPaletteSize << "\n";
  const std::string script_path = dir_ + "/figure.gp";
  {
    std::ofstream s(script_path);
    s << head.str() << script_ << "unset output\n";
    if (!s) throw InputError("cannot write the gnuplot script");
  }
  const std::string log_path = dir_ + "/gnuplot.log";
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  const char* gnuplot = std::getenv("MAGNAV_GNUPLOT") ? std::getenv("MAGNAV_GNUPLOT") : "gnuplot";
  std::vector<char*> argv = {const_cast<char*>(gnuplot), const_cast<char*>(script_path.c_str()), nullptr};
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, gnuplot, &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    throw InputError(std::string("magnav plot needs gnuplot, which could not be started (") + gnuplot +
                     "; apt-get install gnuplot-nox, as scripts/bootstrap does)");
  }
  int status = 0;
  waitpid(pid, &status, 0);
  std::ifstream log(log_path);
  const std::string messages((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw InputError("gnuplot failed: " + messages);
  }
  std::error_code ec;
  if (!fs::exists(picture) || fs::file_size(picture, ec) == 0) throw InputError("gnuplot drew nothing: " + messages);
  // Into place: copy next to the output, then rename (atomic on one file system).
  const fs::path tmp = final_path.string() + ".tmp";
  fs::copy_file(picture, tmp, fs::copy_options::overwrite_existing, ec);
  if (ec) throw InputError("cannot write " + tmp.string() + ": " + ec.message());
  fs::rename(tmp, final_path, ec);
  if (ec) throw InputError("cannot write " + final_path.string() + ": " + ec.message());
}

}  // namespace magnav::tools
