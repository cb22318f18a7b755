#include "relay/physics_link.h"

#include <spdlog/spdlog.h>

#include "protocol/handshake.h"

namespace edgephys {
namespace {

schema::Pose ToPose(uint32_t id, const EntityState& s) {
  return schema::Pose(id, schema::Vec3(s.position.x, s.position.y, s.position.z),
                      schema::Quat(s.rotation.x, s.rotation.y, s.rotation.z, s.rotation.w));
}

}  // namespace

// --- EmbeddedPhysicsLink -----------------------------------------------------------------------

EmbeddedPhysicsLink::EmbeddedPhysicsLink(const physics::PhysicsConfig& config, double now)
    : config_(config),
      physics_(std::make_unique<RoomPhysics>(config, now)),
      clock_{now, 0.0},
      admission_(config),
      meter_(now) {}

EmbeddedPhysicsLink::~EmbeddedPhysicsLink() {
  if (room_ != nullptr) room_->Close();
}

void EmbeddedPhysicsLink::RunOn(AsyncPhysicsPool* pool) {
  if (room_ != nullptr || pool == nullptr) return;
  counters_ = physics_->counters();
  room_ = pool->Adopt(std::move(physics_), config_, clock_);
}

Status EmbeddedPhysicsLink::Add(const schema::Container& c, PhysicsRole role) {
  if (room_ != nullptr) {
    PhysicsCommand command;
    Status st = admission_.Admit(c, role, &command);
    if (st.ok()) room_->Post(std::move(command));
    return st;
  }
  Status st = physics_->Add(c, role);
  if (st.ok()) admission_.Added(c, role);
  return st;
}

void EmbeddedPhysicsLink::Remove(uint32_t id) {
  if (room_ == nullptr) {
    physics_->Remove(id);
    admission_.Removed(id);
    return;
  }
  if (admission_.RoleOf(id) == PhysicsRole::kNone) return;  // not in the world
  admission_.Removed(id);
  room_->Post({.kind = PhysicsCommand::Kind::kRemove, .id = id});
}

void EmbeddedPhysicsLink::Drive(uint32_t id, const EntityState& s, double time) {
  if (room_ == nullptr) return physics_->Drive(id, s, time);
  if (admission_.RoleOf(id) != PhysicsRole::kMirrored) return;  // the world ignores it
  room_->Post({.kind = PhysicsCommand::Kind::kDrive, .id = id, .state = s, .time = time});
}

void EmbeddedPhysicsLink::RequestGrab(uint32_t entity, uint32_t hand, bool force) {
  if (room_ == nullptr) return physics_->RequestGrab(entity, hand, !force);
  room_->Post({.kind = PhysicsCommand::Kind::kGrab, .force = force, .id = entity, .hand = hand});
}

void EmbeddedPhysicsLink::Release(uint32_t entity) {
  if (room_ == nullptr) {
    (void)physics_->Release(entity);
    return;
  }
  room_->Post({.kind = PhysicsCommand::Kind::kRelease, .id = entity});
}

void EmbeddedPhysicsLink::Restore(uint32_t id, const EntityState& s, const Vec3f& l,
                                  const Vec3f& a) {
  if (room_ == nullptr) return physics_->Restore(id, s, l, a);
  room_->Post({.kind = PhysicsCommand::Kind::kRestore, .id = id, .state = s, .linear = l,
               .angular = a});
}

void EmbeddedPhysicsLink::RestoreSoftBody(uint32_t id, std::span<const Vec3f> nodes) {
  if (room_ == nullptr) {
    Status st = physics_->RestoreSoftBody(id, 0, nodes);
    if (!st.ok()) spdlog::warn("PhyS: soft body {} not restored: {}", id, st.ToString());
    return;
  }
  room_->Post({.kind = PhysicsCommand::Kind::kRestoreNodes, .id = id,
               .nodes = std::vector<Vec3f>(nodes.begin(), nodes.end())});
}

void EmbeddedPhysicsLink::Advance(double now, StepOutput* out) {
  if (room_ == nullptr) {
    physics_->Advance(now, out);
    clock_.Record(now, out->steps, config_.fixed_dt);
    if (out->steps > 0) out->state_time = clock_.fed - clock_.acc;
  } else {
    out->Clear();
    room_->Advance(now, &finished_, &used_, &counters_);
    merge_index_.clear();
    for (size_t i = 0; i < finished_.size(); ++i) {
      if (i == 0) {
        std::swap(*out, *finished_[0]);  // the common case: one output, no copy
      } else {
        MergeStepOutput(out, finished_[i].get(), &merge_index_);
      }
      used_.push_back(std::move(finished_[i]));
    }
    finished_.clear();
  }
  meter_.Record(now, out->steps * static_cast<double>(config_.fixed_dt));
}

physics::PhysicsCounters EmbeddedPhysicsLink::counters() const {
  if (room_ == nullptr) return physics_->counters();
  physics::PhysicsCounters c = counters_;
  c.rejected_containers += admission_.rejected();
  return c;
}

// --- RemotePhysicsLink -------------------------------------------------------------------------

RemotePhysicsLink::RemotePhysicsLink(WorkerChannel* channel, uint32_t worker_id,
                                     uint32_t room_handle, const physics::PhysicsConfig& config,
                                     double now)
    : channel_(channel), worker_id_(worker_id), handle_(room_handle), admission_(config),
      last_heard_(now) {
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreateWorkerAssign(fbb, handle_, config.fixed_dt));
  Send(fbb);
}

RemotePhysicsLink::~RemotePhysicsLink() {
  if (registry_ != nullptr) registry_->Unregister(worker_id_, handle_);
  if (channel_ != nullptr && !broken_) {
    flatbuffers::FlatBufferBuilder fbb(32);
    FinishControl(fbb, schema::CreateWorkerUnassign(fbb, handle_));
    Send(fbb);
  }
}

void RemotePhysicsLink::Send(flatbuffers::FlatBufferBuilder& fbb) {
  if (channel_ == nullptr || broken_) return;
  if (!channel_->SendToWorker({fbb.GetBufferPointer(), fbb.GetSize()})) broken_ = true;
}

Status RemotePhysicsLink::Add(const schema::Container& c, PhysicsRole role) {
  // The worker's RoomPhysics::Add decides again, but a refusal there is not answered to the
  // client: the relay refuses exactly what it would, with the embedded link's Status.
  PhysicsCommand unused;
  Status admitted = admission_.Admit(c, role, &unused);
  if (!admitted.ok()) return admitted;
  schema::ContainerT copy;
  c.UnPackTo(&copy);
  flatbuffers::FlatBufferBuilder fbb(1024);
  auto container = schema::Container::Pack(fbb, &copy);
  FinishControl(fbb, schema::CreateWorkerAdd(fbb, handle_, static_cast<uint8_t>(role), container));
  Send(fbb);
  return Status::Ok();
}

void RemotePhysicsLink::Remove(uint32_t id) {
  if (admission_.RoleOf(id) == PhysicsRole::kNone) return;
  admission_.Removed(id);
  flatbuffers::FlatBufferBuilder fbb(32);
  FinishControl(fbb, schema::CreateWorkerRemove(fbb, handle_, id));
  Send(fbb);
}

void RemotePhysicsLink::Drive(uint32_t id, const EntityState& s, double time) {
  if (admission_.RoleOf(id) == PhysicsRole::kNone) return;
  for (size_t i = 0; i < drives_.size(); ++i) {
    if (drives_[i].entity_id() == id) {
      drives_[i] = ToPose(id, s);
      drive_times_[i] = time;
      return;
    }
  }
  drives_.push_back(ToPose(id, s));
  drive_times_.push_back(time);
}

void RemotePhysicsLink::RequestGrab(uint32_t entity, uint32_t hand, bool force) {
  flatbuffers::FlatBufferBuilder fbb(32);
  FinishControl(fbb, schema::CreateWorkerGrab(fbb, handle_, entity, hand, force));
  Send(fbb);
}

void RemotePhysicsLink::Release(uint32_t entity) {
  flatbuffers::FlatBufferBuilder fbb(32);
  FinishControl(fbb, schema::CreateWorkerRelease(fbb, handle_, entity));
  Send(fbb);
}

void RemotePhysicsLink::Restore(uint32_t id, const EntityState& s, const Vec3f& l,
                                const Vec3f& a) {
  flatbuffers::FlatBufferBuilder fbb(96);
  schema::Pose pose = ToPose(id, s);
  schema::Vec3 lin(l.x, l.y, l.z), ang(a.x, a.y, a.z);
  FinishControl(fbb, schema::CreateWorkerRestore(fbb, handle_, id, &pose, &lin, &ang));
  Send(fbb);
}

void RemotePhysicsLink::RestoreSoftBody(uint32_t id, std::span<const Vec3f> nodes) {
  for (size_t first = 0; first < nodes.size(); first += kRestoreNodesPerMessage) {
    const size_t n = std::min(kRestoreNodesPerMessage, nodes.size() - first);
    flatbuffers::FlatBufferBuilder fbb(64 + n * sizeof(schema::Vec3));
    std::vector<schema::Vec3> chunk;
    chunk.reserve(n);
    for (size_t i = 0; i < n; ++i) {
      const Vec3f& v = nodes[first + i];
      chunk.emplace_back(v.x, v.y, v.z);
    }
    auto vec = fbb.CreateVectorOfStructs(chunk);
    schema::WorkerRestoreBuilder b(fbb);
    b.add_room(handle_);
    b.add_entity_id(id);
    b.add_nodes(vec);
    b.add_first_node(static_cast<uint32_t>(first));
    FinishControl(fbb, b.Finish());
    Send(fbb);
  }
}

void RemotePhysicsLink::Advance(double now, StepOutput* out) {
  (void)now;
  if (!drives_.empty()) {
    flatbuffers::FlatBufferBuilder fbb(64 + drives_.size() * (sizeof(schema::Pose) + 8));
    FinishControl(fbb, schema::CreateWorkerDrive(fbb, handle_, fbb.CreateVectorOfStructs(drives_),
                                                 fbb.CreateVector(drive_times_)));
    Send(fbb);
    drives_.clear();
    drive_times_.clear();
  }
  out->Clear();
  std::swap(*out, pending_);
  pending_.Clear();
}

bool RemotePhysicsLink::Healthy(double now) const {
  if (broken_ || channel_ == nullptr || !channel_->WorkerConnected()) return false;
  // A worker reports every room at least every 0.2 s (edgephys-phys sends a heartbeat
  // WorkerResult); silence beyond the stall timeout means it stopped stepping.
  return now - last_heard_ <= stall_timeout_s_;
}

void RemotePhysicsLink::ReceiveResult(const schema::WorkerResult& result, double now) {
  last_heard_ = now;
  if (result.events() != nullptr) {
    for (const schema::PhysicsEvent* ev : *result.events()) {
      physics::PhysicsEvent e{};
      switch (ev->kind()) {
        case schema::PhysicsEventKind::CollisionEnter: e.type = physics::PhysicsEventType::kCollisionEnter; break;
        case schema::PhysicsEventKind::CollisionExit: e.type = physics::PhysicsEventType::kCollisionExit; break;
        case schema::PhysicsEventKind::TriggerEnter: e.type = physics::PhysicsEventType::kTriggerEnter; break;
        case schema::PhysicsEventKind::TriggerExit: e.type = physics::PhysicsEventType::kTriggerExit; break;
        case schema::PhysicsEventKind::GuardReset: e.type = physics::PhysicsEventType::kGuardReset; break;
        default: continue;
      }
      e.entity_a = ev->entity_a();
      e.entity_b = ev->entity_b();
      pending_.events.push_back(e);
    }
  }
  if (result.grabs() != nullptr) {
    for (const schema::WorkerGrabResult* g : *result.grabs()) {
      RoomPhysics::GrabResult r;
      r.entity = g->entity_id();
      r.hand = g->hand_id();
      r.ok = g->ok();
      r.detail = g->detail() ? g->detail()->str() : std::string();
      pending_.grabs.push_back(std::move(r));
    }
  }
}

void RemotePhysicsLink::ReceiveStates(std::span<const uint8_t> payload, double now) {
  uint32_t room = 0;
  if (payload.empty()) return;
  if (payload[0] == kWorkerStateFormat) {
    size_t before = pending_.moved.size();
    if (!DecodeWorkerStates(payload, &room, &pending_.moved).ok() || room != handle_) {
      pending_.moved.resize(before);
      return;
    }
    last_heard_ = now;
    pending_.steps = std::max(pending_.steps, 1);
  } else if (payload[0] == kWorkerSoftFormat) {
    SoftBodyChunk chunk;
    if (!DecodeWorkerSoftChunk(payload, &room, &chunk).ok() || room != handle_) return;
    last_heard_ = now;
    RoomPhysics::SoftNodes part;
    part.id = chunk.entity_id;
    part.total = chunk.total;
    part.first = chunk.first;
    part.nodes = std::move(chunk.positions);
    pending_.soft.push_back(std::move(part));
  }
}

}  // namespace edgephys
