// Drawing with gnuplot (Debian's gnuplot-nox): `magnav plot` writes each data
// series to a file in a private temporary directory and a gnuplot script that
// draws them, runs gnuplot on it, and renames the picture into place (an
// error never leaves a half-written picture). SVG, PNG or PDF (cairo), by
// the output's ending or a format named explicitly. Text is drawn as written
// (gnuplot's terminals are set `noenhanced`: an underscore is an underscore,
// not a subscript).
#pragma once

#include <string>
#include <vector>

namespace magnav::tools {

// The qualitative palette of every figure: Okabe & Ito's colour-blind-safe
// set (Color Universal Design, 2008) without its yellow (invisible on white),
// in the order series take them. Gnuplot's line types 1..7 are set to it.
inline constexpr const char* kPalette[] = {"#0072B2", "#D55E00", "#009E73", "#CC79A7",
                                           "#E69F00", "#56B4E9", "#000000"};
inline constexpr int kPaletteSize = 7;
// `lc rgb '<colour>'` of series i (cycling through kPalette).
std::string PaletteColour(int i);

// "svg", "png" or "pdf" from an output path's ending; "" for any other.
std::string PictureFormatOf(const std::string& output);

class GnuplotFigure {
 public:
  // format: "svg", "png", "pdf", or "" to take it from the output's ending.
  // Throws InputError if the format is none of these, or if an explicit
  // format disagrees with the output's ending. Width and height are pixels
  // for SVG and PNG; a PDF is drawn at 1/100 in per pixel (900 x 750 px:
  // 9 x 7.5 in).
  GnuplotFigure(const std::string& output, int width_px = 900, int height_px = 750,
                const std::string& format = "");
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
  std::string output_, dir_, script_, format_;
  int width_px_, height_px_;
};

}  // namespace magnav::tools
