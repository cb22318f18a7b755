// chart: the one gnuplot chart writer of the load generator's scenarios and the bench reports.
//
// A Chart is plot commands (`body`) plus the terminals it is drawn with; Write() puts them into
// gnuplot scripts, Render() runs gnuplot on those scripts. Two script layouts:
//   kScriptPerFormat  <dir>/<stem>.png.gp and <dir>/<stem>.svg.gp, each
//                     "set terminal T\nset output '<stem>.<fmt>'\n" + body (edgephys-loadgen).
//   kLoopScript       one <dir>/<stem>.gp, "# comment" then a `do for [fmt in "png svg"]` loop
//                     that sets the terminal and `set output "<stem>.".fmt`, runs the body
//                     (indented by its author) and closes multiplot and output
//                     (physics_accuracy_report).
// `stem` is relative to the directory gnuplot runs in: the current one for kScriptPerFormat
// (so stem may carry a path and `dir` stays empty), `dir` for kLoopScript.
#pragma once

#include <string>

namespace edgephys::chart {

// What follows `set terminal` for each image format.
struct Terminals {
  std::string png;
  std::string svg;
  // kScriptPerFormat: the png terminal retried when gnuplot fails on `png` (no cairo); "" for
  // no retry.
  std::string png_fallback;
};

// Gnuplot's default font and enhanced text: "pngcairo size W,H", "svg size W,H", falling back
// to "png size W,H" (relay-compare, multiobject, softbody, ccu).
Terminals PlainTerminals(int width = 900, int height = 560);
// noenhanced text, sans 10 (png) / 11 (svg), white svg background, falling back to
// "png noenhanced size W,H" (interp-sweep, codec-sweep).
Terminals LabelTerminals(int width = 800, int height = 500);
// `font "sans,9" noenhanced` on pngcairo and svg, no fallback (physics_accuracy_report).
Terminals ReportTerminals(int width, int height);

enum class Layout { kScriptPerFormat, kLoopScript };

struct Chart {
  std::string stem;  // the images are <stem>.png and <stem>.svg
  std::string body;  // plot commands, everything after `set terminal` / `set output`
  Terminals terminals = PlainTerminals();
  Layout layout = Layout::kScriptPerFormat;
  std::string dir;      // where the scripts are written; "" for the current directory
  std::string comment;  // kLoopScript: the script's first line, after "# "
};

// Writes the chart's script(s). False if one could not be written.
bool Write(const Chart& chart);

// True if gnuplot is on PATH.
bool HaveGnuplot();

// Runs gnuplot on the scripts Write() wrote; true if it drew every image.
//   kScriptPerFormat: skipped (true) without gnuplot on PATH; gnuplot's messages are discarded;
//                     a png that fails is rewritten and retried with png_fallback.
//   kLoopScript:      `cd <dir> && gnuplot <stem>.gp`, its messages on stderr.
bool Render(const Chart& chart);

}  // namespace edgephys::chart
