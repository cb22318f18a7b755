#include "loadgen/emulation/emulation_plugins.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <utility>
#include <vector>

#include "loadgen/emulation/emulation_codec.h"
#include "protocol/replication_tracker.h"
#include "relay/entity.h"

namespace edgephys {
namespace {

float Distance(const Vec3f& a, const Vec3f& b) {
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

float AngleDeg(const Quatf& a, const Quatf& b) {
  const float dot = std::fabs(a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w);
  return 2.0f * std::acos(std::min(1.0f, dot)) * 57.29578f;
}

// Format 1: exact floats, every version until acknowledged (ReplicationTracker).
class FloatStream final : public StateStream {
 public:
  StreamNeed Want(const StreamEntity& e, double now, double resend_after_s, uint8_t*) override {
    return tracker_.NeedsSend(e.id, e.version, now, resend_after_s) ? StreamNeed::kSend
                                                                    : StreamNeed::kSkip;
  }
  void Begin(std::span<uint8_t> out, uint32_t time_ms) override {
    encoder_.Begin(out, time_ms);
    in_payload_.clear();
  }
  bool Add(const StreamEntity& e, uint8_t) override {
    if (!encoder_.Add(*e.state)) return false;
    in_payload_.emplace_back(e.id, e.version);
    return true;
  }
  size_t count() const override { return encoder_.count(); }
  size_t Finish() override { return encoder_.Finish(); }
  void OnSent(uint16_t sequence, double now) override {
    for (const auto& [id, version] : in_payload_) tracker_.OnSent(sequence, id, version, now);
  }
  void OnAcked(uint16_t sequence) override { tracker_.OnAcked(sequence); }
  void Forget(uint32_t entity_id) override { tracker_.Forget(entity_id); }

 private:
  FloatStateEncoder encoder_;
  ReplicationTracker tracker_;
  std::vector<std::pair<uint32_t, uint32_t>> in_payload_;  // (id, version)
};

// Format 3: every due entity, changed or not (the fixed rate decides); no acknowledgements.
class PhotonStream final : public StateStream {
 public:
  StreamNeed Want(const StreamEntity&, double, double, uint8_t*) override {
    return StreamNeed::kSend;
  }
  void Begin(std::span<uint8_t> out, uint32_t time_ms) override { encoder_.Begin(out, time_ms); }
  bool Add(const StreamEntity& e, uint8_t) override { return encoder_.Add(*e.state); }
  size_t count() const override { return encoder_.count(); }
  size_t Finish() override { return encoder_.Finish(); }
  void OnSent(uint16_t, double) override {}
  void OnAcked(uint16_t) override {}
  void Forget(uint32_t) override {}

 private:
  PhotonEmulationEncoder encoder_;
};

// Format 4: the fields that moved beyond the thresholds since the last SENT state (the paper's
// significance test; nothing is acknowledged).
class PaperStream final : public StateStream {
 public:
  explicit PaperStream(const ReplicationConfig& config)
      : position_threshold_m_(config.position_threshold_m),
        rotation_threshold_deg_(config.rotation_threshold_deg) {}
  StreamNeed Want(const StreamEntity& e, double, double, uint8_t* fields) override {
    auto it = last_sent_.find(e.id);
    if (it == last_sent_.end()) return StreamNeed::kSend;  // never sent: both fields
    *fields = 0;
    if (Distance(e.state->position, it->second.position) > position_threshold_m_) {
      *fields |= kFieldPosition;
    }
    if (AngleDeg(e.state->rotation, it->second.rotation) > rotation_threshold_deg_) {
      *fields |= kFieldRotation;
    }
    return *fields != 0 ? StreamNeed::kSend : StreamNeed::kSkip;
  }
  void Begin(std::span<uint8_t> out, uint32_t time_ms) override { encoder_.Begin(out, time_ms); }
  bool Add(const StreamEntity& e, uint8_t fields) override {
    if (!encoder_.AddFields(*e.state, fields)) return false;
    EntityState& last = last_sent_[e.id];
    if (fields & kFieldPosition) last.position = e.state->position;
    if (fields & kFieldRotation) last.rotation = e.state->rotation;
    return true;
  }
  size_t count() const override { return encoder_.count(); }
  size_t Finish() override { return encoder_.Finish(); }
  void OnSent(uint16_t, double) override {}
  void OnAcked(uint16_t) override {}
  void Forget(uint32_t entity_id) override { last_sent_.erase(entity_id); }

 private:
  float position_threshold_m_;
  float rotation_threshold_deg_;
  PaperEmulationEncoder encoder_;
  std::unordered_map<uint32_t, EntityState> last_sent_;
};

class EmulationPlugin final : public ReplicationPlugin {
 public:
  explicit EmulationPlugin(ReplicationMode mode) : mode_(mode) {}
  std::string_view name() const override { return ReplicationModeName(mode_); }
  uint8_t state_format() const override {
    switch (mode_) {
      case ReplicationMode::kPhoton: return kFormatPhoton;
      case ReplicationMode::kPaper: return kFormatPaper;
      default: return static_cast<uint8_t>(StateFormat::kFloat);
    }
  }
  std::unique_ptr<StateStream> NewStream(const ReplicationConfig& config) const override {
    switch (mode_) {
      case ReplicationMode::kPhoton: return std::make_unique<PhotonStream>();
      case ReplicationMode::kPaper: return std::make_unique<PaperStream>(config);
      default: return std::make_unique<FloatStream>();
    }
  }

 private:
  ReplicationMode mode_;
};

class EmulationDecoder final : public StateDecoderPlugin {
 public:
  Status Decode(std::span<const uint8_t> payload, const Known& known,
                StateBatch* batch) const override {
    if (!payload.empty() && payload[0] == static_cast<uint8_t>(StateFormat::kFloat)) {
      return DecodeStateBatch(payload, batch);
    }
    return DecodeEmulationBatch(payload, batch, known);
  }
};

}  // namespace

std::string_view ReplicationModeName(ReplicationMode mode) {
  switch (mode) {
    case ReplicationMode::kEdgephys: return "edgephys";
    case ReplicationMode::kFloat: return "float";
    case ReplicationMode::kPhoton: return "photon";
    case ReplicationMode::kPaper: return "paper";
  }
  return "unknown";
}

bool ParseReplicationMode(std::string_view text, ReplicationMode* mode) {
  for (ReplicationMode m : {ReplicationMode::kEdgephys, ReplicationMode::kFloat,
                            ReplicationMode::kPhoton, ReplicationMode::kPaper}) {
    if (text == ReplicationModeName(m)) {
      *mode = m;
      return true;
    }
  }
  return false;
}

std::shared_ptr<const ReplicationPlugin> ReplicationPluginFor(ReplicationMode mode) {
  if (mode == ReplicationMode::kEdgephys) return nullptr;
  return std::make_shared<const EmulationPlugin>(mode);
}

void UseReplicationMode(ReplicationMode mode, ReplicationConfig* config) {
  config->plugin = ReplicationPluginFor(mode);
}

std::shared_ptr<const StateDecoderPlugin> EmulationStateDecoder() {
  static const auto decoder = std::make_shared<const EmulationDecoder>();
  return decoder;
}

}  // namespace edgephys
