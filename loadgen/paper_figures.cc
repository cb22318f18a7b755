#include "loadgen/paper_figures.h"

#include <span>
#include <utility>

namespace edgephys::loadgen {
namespace {

using Table = std::span<const std::pair<uint32_t, double>>;

double Lookup(Table table, uint32_t size) {
  for (const auto& [n, figure] : table) {
    if (n == size) return figure;
  }
  return 0;
}

constexpr std::pair<uint32_t, double> kRelayBytesPerS[] = {
    {32, 12560}, {64, 24860}, {128, 49500}, {256, 96800}, {512, 193600}};
constexpr std::pair<uint32_t, double> kPhotonBytesPerS[] = {
    {32, 16520}, {64, 32580}, {128, 63000}, {256, 130500}, {512, 257400}};
constexpr std::pair<uint32_t, double> kObjMbitPerS[] = {
    {500, 0.72}, {1000, 1.32}, {2000, 2.70}, {5000, 5.45}, {7500, 8.31}, {10000, 10.95}};
constexpr std::pair<uint32_t, double> kBunnyMbitPerS[] = {{1, 0.46}, {3, 1.40}};

}  // namespace

double PaperRelayBytesPerS(uint32_t objects) { return Lookup(kRelayBytesPerS, objects); }
double PaperPhotonBytesPerS(uint32_t objects) { return Lookup(kPhotonBytesPerS, objects); }
double PaperObjMbitPerS(uint32_t objects) { return Lookup(kObjMbitPerS, objects); }
double PaperBunnyMbitPerS(uint32_t bunnies) { return Lookup(kBunnyMbitPerS, bunnies); }

}  // namespace edgephys::loadgen
