// Drawing with gnuplot (Debian's gnuplot-nox): `magnav plot` writes each data
// series to a file in a private temporary directory and a gnuplot script that
// draws them, runs gnuplot on it, and renames the picture into place (an
// error never leaves a half-written picture). SVG or PNG by the output's
// ending.
#pragma once

#include <string>
#include <vector>

namespace magnav::tools {

class GnuplotFigure {
 public:
  // Throws InputError if the output ending is neither .svg nor .png.
  GnuplotFigure(const std::string& output, int width_px = 900, int height_px = 750);
  ~GnuplotFigure();  // removes the temporary directory
  GnuplotFigure(const GnuplotFigure&) = delete;
  GnuplotFigure& operator=(const GnuplotFigure&) = delete;

  // Writes rows (whitespace-separated numbers; an empty row separates
  // blocks for `index`/lines) to a data file; returns its quoted path for
  // the script.
  std::string Data(const std::string& name, const std::vector<std::vector<double>>& rows);
  // Appends script lines (after the terminal and output lines).
  void Script(const std::string& lines);
  // Runs gnuplot; throws InputError with gnuplot's message if it fails or
  // is missing, or if the picture is empty.
  void Render();

 private:
  std::string output_, dir_, script_;
  int width_px_, height_px_;
  bool svg_ = true;
};

}  // namespace magnav::tools
