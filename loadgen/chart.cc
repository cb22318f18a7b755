#include "loadgen/chart.h"

#include <cstdlib>
#include <fstream>
#include <string_view>

namespace edgephys::chart {
namespace {

std::string Size(int width, int height) {
  return std::to_string(width) + "," + std::to_string(height);
}

// `name` in the chart's directory.
std::string InDir(const Chart& chart, const std::string& name) {
  return chart.dir.empty() ? name : chart.dir + "/" + name;
}

// The script of one format (kScriptPerFormat) or of both (kLoopScript), relative to `dir`.
std::string ScriptName(const Chart& chart, std::string_view format) {
  return chart.layout == Layout::kLoopScript ? chart.stem + ".gp"
                                             : chart.stem + "." + std::string(format) + ".gp";
}

bool WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  if (!out) return false;
  out << text;
  out.close();
  return static_cast<bool>(out);
}

std::string PerFormatScript(const Chart& chart, const std::string& terminal,
                            std::string_view format) {
  return "set terminal " + terminal + "\nset output '" + chart.stem + "." + std::string(format) +
         "'\n" + chart.body;
}

std::string LoopScript(const Chart& chart) {
  std::string s;
  if (!chart.comment.empty()) s += "# " + chart.comment + "\n";
  s += "do for [fmt in \"png svg\"] {\n";
  s += "  if (fmt eq \"png\") { set terminal " + chart.terminals.png + " } else { set terminal " +
       chart.terminals.svg + " }\n";
  s += "  set output \"" + chart.stem + ".\".fmt\n";
  s += chart.body;
  s += "  unset multiplot\n  set output\n  reset\n}\n";
  return s;
}

// gnuplot on `script` (relative to the chart's directory).
bool RunGnuplot(const Chart& chart, const std::string& script, bool quiet) {
  std::string cmd = chart.dir.empty() ? "" : "cd '" + chart.dir + "' && ";
  cmd += "gnuplot '" + script + "'";
  if (quiet) cmd += " 2>/dev/null";
  return std::system(cmd.c_str()) == 0;
}

}  // namespace

Terminals PlainTerminals(int width, int height) {
  const std::string size = Size(width, height);
  return {"pngcairo size " + size, "svg size " + size, "png size " + size};
}

Terminals LabelTerminals(int width, int height) {
  const std::string size = Size(width, height);
  return {"pngcairo noenhanced size " + size + " font 'sans,10'",
          "svg noenhanced size " + size + " font 'sans,11' background '#ffffff'",
          "png noenhanced size " + size};
}

Terminals ReportTerminals(int width, int height) {
  const std::string size = Size(width, height);
  return {"pngcairo size " + size + " font \"sans,9\" noenhanced",
          "svg size " + size + " font \"sans,9\" noenhanced", ""};
}

bool Write(const Chart& chart) {
  if (chart.layout == Layout::kLoopScript) {
    return WriteFile(InDir(chart, ScriptName(chart, "")), LoopScript(chart));
  }
  return WriteFile(InDir(chart, ScriptName(chart, "png")),
                   PerFormatScript(chart, chart.terminals.png, "png")) &&
         WriteFile(InDir(chart, ScriptName(chart, "svg")),
                   PerFormatScript(chart, chart.terminals.svg, "svg"));
}

bool HaveGnuplot() { return std::system("command -v gnuplot >/dev/null 2>&1") == 0; }

bool Render(const Chart& chart) {
  if (chart.layout == Layout::kLoopScript) {
    return RunGnuplot(chart, ScriptName(chart, ""), /*quiet=*/false);
  }
  if (!HaveGnuplot()) return true;
  bool ok = true;
  if (!RunGnuplot(chart, ScriptName(chart, "png"), true)) {
    ok = !chart.terminals.png_fallback.empty() &&
         WriteFile(InDir(chart, ScriptName(chart, "png")),
                   PerFormatScript(chart, chart.terminals.png_fallback, "png")) &&
         RunGnuplot(chart, ScriptName(chart, "png"), true);
  }
  return RunGnuplot(chart, ScriptName(chart, "svg"), true) && ok;
}

}  // namespace edgephys::chart
