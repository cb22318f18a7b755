// state_fuzz: every state payload decoder and the join token parser.
//
// Input: u8 mode | records (u8 tag | u16 length | bytes), at most kMaxRecords. By tag % 7 a
// record goes to (for 1..5 its first byte is replaced by that decoder's format byte):
//   0: DecodeStateBatch (format 1; any first byte)
//   1: DeltaDecoder::Decode (format 2), or with tag bit 3 SharedDeltaDecoder::Decode (format
//      9). One decoder of each per input sees every record of its format in order, so later
//      payloads resolve references to earlier ones. mode bit 0: the decoders'
//      quantisation comes from the first 32 bytes of the input after the mode byte (as a
//      client builds it from the relay's Joined message), when MakeQuantizationParams accepts.
//   2: DecodeEmulationBatch (tag bit 3: format 4 "paper", else 3 "photon"), looking up the
//      states decoded so far by this input
//   3: DecodeSoftBodyChunk (format 5), or with tag bit 4 SoftDeltaReceiver::Decode (format 11;
//      one receiver per input sees every such record in order, so later payloads resolve
//      baselines decoded earlier)
//   4: DecodeWorkerStates (format 6)
//   5: DecodeWorkerSoftChunk (format 8)
//   6: VerifyJoinToken on the bytes, and on the relay part when they split as a client token;
//      Base64UrlDecode of the bytes as text (and the token in it); SignJoinToken ->
//      SplitClientToken -> VerifyJoinToken round trip of a token built from the bytes (the
//      session secret the relay decrypts is the client's)
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <unordered_map>

#include "physics_backend/worker_protocol.h"
#include "protocol/delta_codec.h"
#include "loadgen/emulation/emulation_codec.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/quantize.h"
#include "protocol/shared_delta_codec.h"
#include "protocol/soft_body_codec.h"
#include "protocol/soft_delta_stream.h"
#include "protocol/state_codec.h"
#include "tests/fuzz/fuzz_world.h"

namespace edgephys::fuzz {
namespace {

constexpr size_t kMaxRecords = 64;

float F32(Reader& in) {
  uint32_t bits = in.U16();
  bits |= static_cast<uint32_t>(in.U16()) << 16;
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

std::vector<uint8_t> WithFormat(std::span<const uint8_t> bytes, uint8_t format) {
  std::vector<uint8_t> out(bytes.begin(), bytes.end());
  if (out.empty()) out.push_back(format);
  out[0] = format;
  return out;
}

void CheckTokens(std::span<const uint8_t> bytes) {
  TokenError error = TokenError::kNone;
  auto direct = VerifyJoinToken(bytes, kFuzzSecret, kUnixNow, &error);
  if (!direct.ok()) {
    EDGEPHYS_FUZZ_CHECK(error != TokenError::kNone);
    EDGEPHYS_FUZZ_CHECK(!direct.status().detail().empty());  // every refusal names its cause
  }
  auto split = SplitClientToken(bytes);
  if (split.ok()) {
    EDGEPHYS_FUZZ_CHECK(split->relay_token.size() + kSessionSecretSize == bytes.size());
    auto relay = VerifyJoinToken(split->relay_token, kFuzzSecret, kUnixNow, &error);
    if (relay.ok()) {
      // The relay part alone decides admission; a client token whose tail (the secret) was
      // altered still splits, but its Connect proof only matches the relay's when the
      // secrets agree, so such a client is refused with BadProof.
      const ConnectTranscript t{.client_nonce = 7, .token = split->relay_token};
      const bool same = relay->session_secret == split->session_secret;
      EDGEPHYS_FUZZ_CHECK((ConnectProof(split->session_secret, t) ==
                           ConnectProof(relay->session_secret, t)) == same);
    }
  }

  std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  auto decoded = Base64UrlDecode(text);
  if (decoded.ok()) {
    (void)VerifyJoinToken(*decoded, kFuzzSecret, kUnixNow, &error);
    auto again = Base64UrlDecode(Base64UrlEncode(*decoded));
    EDGEPHYS_FUZZ_CHECK(again.ok() && *again == *decoded);
  }

  // A token signed with the secret verifies and round-trips.
  Reader in(bytes.data(), bytes.size());
  JoinToken t;
  t.player_id = in.U16() | (static_cast<uint32_t>(in.U16()) << 16);
  t.permissions = in.U16();
  t.expiry_unix_s = kUnixNow + 1 + in.U16();
  t.nonce = in.U16();
  t.session_secret.fill(in.U8());  // zero: SignJoinToken draws one
  auto room = in.Bytes(in.U8() % 80);
  t.room.assign(room.begin(), room.end());
  auto signed_token = SignJoinToken(t, kFuzzSecret);
  if (!signed_token.ok()) return;
  EDGEPHYS_FUZZ_CHECK(signed_token->size() <= kMaxClientTokenSize);
  auto client = SplitClientToken(*signed_token);
  EDGEPHYS_FUZZ_CHECK(client.ok());
  EDGEPHYS_FUZZ_CHECK(client->relay_token.size() <= kMaxJoinTokenSize);
  EDGEPHYS_FUZZ_CHECK(!VerifyJoinToken(*signed_token, kFuzzSecret, kUnixNow, &error).ok());
  auto verified = VerifyJoinToken(client->relay_token, kFuzzSecret, kUnixNow, &error);
  EDGEPHYS_FUZZ_CHECK(verified.ok());
  EDGEPHYS_FUZZ_CHECK(verified->room == t.room && verified->player_id == t.player_id &&
                      verified->permissions == t.permissions &&
                      verified->expiry_unix_s == t.expiry_unix_s && verified->nonce == t.nonce);
  EDGEPHYS_FUZZ_CHECK(verified->session_secret == client->session_secret);
  if (t.session_secret != SessionSecret{}) {
    EDGEPHYS_FUZZ_CHECK(client->session_secret == t.session_secret);
  }
  EDGEPHYS_FUZZ_CHECK(
      !VerifyJoinToken(client->relay_token, "another-secret", kUnixNow, &error).ok());
}

}  // namespace
}  // namespace edgephys::fuzz

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace edgephys;
  using namespace edgephys::fuzz;
  Reader in(data, size);
  const uint8_t mode = in.U8();

  QuantizationConfig q;
  if (mode & 1) {
    QuantizationConfig custom;
    custom.bounds_min = {F32(in), F32(in), F32(in)};
    custom.bounds_max = {F32(in), F32(in), F32(in)};
    custom.position_step_m = F32(in);
    custom.rotation_error_deg = F32(in);
    if (MakeQuantizationParams(custom).ok()) q = custom;
  }
  auto params = MakeQuantizationParams(q);
  EDGEPHYS_FUZZ_CHECK(params.ok());
  DeltaDecoder delta(*params, /*max_entities=*/4096);
  SharedDeltaDecoder shared(*params, /*max_entities=*/4096);

  StateBatch batch;
  std::unordered_map<uint32_t, EntityState> known;  // for format 4 lookups
  SoftBodyChunk chunk;
  SoftDeltaReceiver soft(0.001f, 1 << 16, /*max_bodies=*/64, /*max_held_particles=*/1 << 16);
  std::vector<RoomPhysics::MovedBody> bodies;
  for (size_t i = 0; i < kMaxRecords && !in.empty(); ++i) {
    const uint8_t tag = in.U8();
    auto bytes = in.Bytes(in.U16());
    switch (tag % 7) {
      case 0:
        if (DecodeStateBatch(bytes, &batch).ok()) {
          EDGEPHYS_FUZZ_CHECK(batch.states.size() <= bytes.size());
          for (const EntityState& s : batch.states) known[s.entity_id] = s;
        }
        break;
      case 1: {
        const bool format9 = (tag & 8) != 0;
        auto payload = WithFormat(bytes, format9 ? kSharedDeltaStateFormat : kDeltaStateFormat);
        const size_t before = batch.states.size();
        if ((format9 ? shared.Decode(payload, &batch) : delta.Decode(payload, &batch)).ok()) {
          for (size_t k = before; k < batch.states.size(); ++k) {
            const EntityState& s = batch.states[k];
            // Decoded states lie on the lattice inside the bounds and are finite.
            EDGEPHYS_FUZZ_CHECK(std::isfinite(s.position.x) && std::isfinite(s.position.y) &&
                                std::isfinite(s.position.z) && std::isfinite(s.rotation.w));
          }
        }
        batch.states.clear();
        break;
      }
      case 2: {
        auto payload = WithFormat(bytes, (tag & 8) ? kFormatPaper : kFormatPhoton);
        auto lookup = [&known](uint32_t id, EntityState* s) {
          auto it = known.find(id);
          if (it == known.end()) return false;
          *s = it->second;
          return true;
        };
        if (DecodeEmulationBatch(payload, &batch, lookup).ok()) {
          for (const EntityState& s : batch.states) known[s.entity_id] = s;
        }
        break;
      }
      case 3: {
        if (tag & 16) {
          auto payload = WithFormat(bytes, kSoftDeltaFormat);
          (void)soft.Decode(payload);
          for (const SoftDeltaUpdate& u : soft.updates()) {
            const auto shown = soft.Display(u.id);
            EDGEPHYS_FUZZ_CHECK(u.count >= 1 && size_t{u.first} + u.count <= shown.size());
            for (uint32_t k = u.first; k < u.first + u.count; ++k) {
              EDGEPHYS_FUZZ_CHECK(std::isfinite(shown[k].x) && std::isfinite(shown[k].y) &&
                                  std::isfinite(shown[k].z));
            }
          }
          break;
        }
        auto payload = WithFormat(bytes, kSoftBodyFormat);
        const float step = (tag & 8) ? 0.001f : 0.0001f;
        if (DecodeSoftBodyChunk(payload, step, 1 << 16, &chunk).ok()) {
          EDGEPHYS_FUZZ_CHECK(chunk.total <= (1u << 16) && chunk.first < chunk.total &&
                              chunk.positions.size() <= chunk.total - chunk.first);
        }
        break;
      }
      case 4: {
        auto payload = WithFormat(bytes, kWorkerStateFormat);
        uint32_t room = 0;
        bodies.clear();
        if (DecodeWorkerStates(payload, &room, &bodies).ok()) {
          EDGEPHYS_FUZZ_CHECK(bodies.size() <= payload.size());
        }
        break;
      }
      case 5: {
        auto payload = WithFormat(bytes, kWorkerSoftFormat);
        uint32_t room = 0;
        (void)DecodeWorkerSoftChunk(payload, &room, &chunk);
        break;
      }
      case 6:
        CheckTokens(bytes);
        break;
    }
    if (known.size() > 65536) known.clear();
  }
  return 0;
}
