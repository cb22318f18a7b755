#include "loadgen/report.h"

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

namespace edgephys::loadgen {

std::string RelayCompareJson(const RelayCompareOptions& o,
                             const std::vector<RelayCompareResult>& results) {
  nlohmann::json j;
  j["scenario"] = "relay-compare";
  j["options"] = {{"rate_hz", o.rate_hz},         {"duration_s", o.duration_s},
                  {"receivers", o.receivers},     {"speed_mps", o.motion.speed_mps},
                  {"spin_dps", o.motion.spin_dps}, {"seed", o.motion.seed},
                  {"position_step_m", o.position_step_m},
                  {"rotation_bound_deg", o.rotation_bound_deg}};
  j["results"] = nlohmann::json::array();
  for (const auto& r : results) {
    j["results"].push_back({{"mode", std::string(ReplicationModeName(r.mode))},
                            {"objects", r.objects},
                            {"rate_hz", r.rate_hz},
                            {"egress_bytes_per_s_per_receiver", r.egress_bytes_per_s_per_receiver},
                            {"socket_bytes_per_s_per_receiver", r.socket_bytes_per_s_per_receiver},
                            {"updates_per_s_per_receiver", r.updates_per_s_per_receiver},
                            {"bytes_per_update", r.bytes_per_update},
                            {"pos_err_max_m", r.pos_err_max_m},
                            {"pos_err_p99_m", r.pos_err_p99_m},
                            {"rot_err_max_deg", r.rot_err_max_deg},
                            {"rot_err_p99_deg", r.rot_err_p99_deg},
                            {"paper_bytes_per_s", r.paper_bytes_per_s},
                            {"ratio_to_paper", r.paper_bytes_per_s > 0
                                                   ? r.egress_bytes_per_s_per_receiver / r.paper_bytes_per_s
                                                   : 0.0},
                            {"samples", r.samples}});
  }
  return j.dump(2);
}

std::string RelayCompareTable(const std::vector<RelayCompareResult>& results) {
  std::ostringstream out;
  char line[256];
  std::snprintf(line, sizeof(line), "%-9s %7s %11s %11s %9s %7s %9s %7s %9s %9s %9s %9s\n",
                "mode", "objects", "KB/s relay", "KB/s sock", "paper KB/s", "ratio", "upd/s",
                "B/upd", "pos max mm", "pos p99", "rot max", "rot p99");
  out << line;
  for (const auto& r : results) {
    double paper = r.paper_bytes_per_s;
    std::snprintf(line, sizeof(line),
                  "%-9s %7u %11.2f %11.2f %9.2f %7.3f %9.1f %7.2f %9.3f %9.3f %9.4f %9.4f\n",
                  std::string(ReplicationModeName(r.mode)).c_str(), r.objects,
                  r.egress_bytes_per_s_per_receiver / 1000, r.socket_bytes_per_s_per_receiver / 1000,
                  paper / 1000, paper > 0 ? r.egress_bytes_per_s_per_receiver / paper : 0.0,
                  r.updates_per_s_per_receiver, r.bytes_per_update, r.pos_err_max_m * 1000,
                  r.pos_err_p99_m * 1000, r.rot_err_max_deg, r.rot_err_p99_deg);
    out << line;
  }
  out << "(KB = 1000 bytes; paper KB/s: the paper's relay column for paper/edgephys, Photon for photon)\n";
  return out.str();
}

bool WriteRelayCompareCharts(const std::vector<RelayCompareResult>& results,
                             const std::string& prefix) {
  std::ofstream dat(prefix + ".dat");
  if (!dat) return false;
  // One block per mode (gnuplot "index").
  const char* modes[] = {"photon", "paper", "edgephys", "float"};
  int blocks = 0;
  std::vector<std::string> present;
  for (const char* m : modes) {
    bool any = false;
    for (const auto& r : results) {
      if (ReplicationModeName(r.mode) != m) continue;
      if (!any) dat << "# mode " << m << "\n# objects kBps_relay kBps_paper pos_max_mm rot_max_deg\n";
      any = true;
      dat << r.objects << " " << r.egress_bytes_per_s_per_receiver / 1000 << " "
          << r.paper_bytes_per_s / 1000 << " " << r.pos_err_max_m * 1000 << " "
          << r.rot_err_max_deg << "\n";
    }
    if (any) {
      dat << "\n\n";
      present.push_back(m);
      ++blocks;
    }
  }
  dat.close();
  auto write_gp = [&](const std::string& name, const std::string& body) {
    for (const char* term : {"pngcairo size 900,560", "svg size 900,560"}) {
      std::string ext = std::string(term).rfind("png", 0) == 0 ? ".png" : ".svg";
      std::ofstream gp(prefix + "_" + name + ext + ".gp");
      gp << "set terminal " << term << "\nset output '" << prefix << "_" << name << ext << "'\n"
         << body;
      gp.close();
      if (std::system("command -v gnuplot >/dev/null 2>&1") == 0) {
        std::string cmd = "gnuplot '" + prefix + "_" + name + ext + ".gp' 2>/dev/null";
        if (std::system(cmd.c_str()) != 0) {
          // The png terminal may lack cairo; fall back to plain png.
          std::ofstream gp2(prefix + "_" + name + ext + ".gp");
          gp2 << "set terminal png size 900,560\nset output '" << prefix << "_" << name << ext
              << "'\n" << body;
          gp2.close();
          (void)std::system(cmd.c_str());
        }
      }
    }
  };
  std::ostringstream bw;
  bw << "set title 'Relay egress per receiver vs objects (12 sends/s per object)'\n"
        "set xlabel 'objects'\nset ylabel 'KB/s per receiver'\nset logscale xy\nset key top left\n"
        "set grid\nplot ";
  for (int i = 0; i < blocks; ++i) {
    bw << "'" << prefix << ".dat' index " << i << " using 1:2 with linespoints title '" << present[i]
       << " (measured)', ";
  }
  bw << "'" << prefix << ".dat' index 0 using 1:3 with points pt 6 ps 1.5 title 'paper: Photon', ";
  bw << "'" << prefix << ".dat' index 1 using 1:3 with points pt 8 ps 1.5 title 'paper: relay'\n";
  write_gp("bandwidth", bw.str());
  std::ostringstream err;
  err << "set title 'Bandwidth vs accuracy (max error of the last received state)'\n"
         "set xlabel 'KB/s per receiver'\nset ylabel 'max position error (mm)'\nset logscale x\n"
         "set y2label 'max rotation error (deg)'\nset y2tics\nset grid\nset key top right\nplot ";
  for (int i = 0; i < blocks; ++i) {
    err << "'" << prefix << ".dat' index " << i << " using 2:4 with linespoints title '" << present[i]
        << " position', '" << prefix << ".dat' index " << i << " using 2:5 axes x1y2 with points title '"
        << present[i] << " rotation'" << (i + 1 < blocks ? ", " : "\n");
  }
  write_gp("error", err.str());
  return true;
}

}  // namespace edgephys::loadgen
