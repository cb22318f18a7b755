#include "physics_backend/worker.h"

#include <spdlog/spdlog.h>

#include "physics_backend/worker_protocol.h"
#include "protocol/handshake.h"
#include "client/protocol_peer.h"

namespace edgephys {
namespace {

schema::PhysicsEventKind KindOf(physics::PhysicsEventType t) {
  switch (t) {
    case physics::PhysicsEventType::kCollisionEnter: return schema::PhysicsEventKind::CollisionEnter;
    case physics::PhysicsEventType::kCollisionExit: return schema::PhysicsEventKind::CollisionExit;
    case physics::PhysicsEventType::kTriggerEnter: return schema::PhysicsEventKind::TriggerEnter;
    case physics::PhysicsEventType::kTriggerExit: return schema::PhysicsEventKind::TriggerExit;
    case physics::PhysicsEventType::kGuardReset: return schema::PhysicsEventKind::GuardReset;
  }
  return schema::PhysicsEventKind::GuardReset;
}

}  // namespace

void PhysicsWorker::OnConnected(uint32_t /*player_id*/) {
  flatbuffers::FlatBufferBuilder fbb(32);
  FinishControl(fbb, schema::CreateWorkerHello(fbb, 64));
  (void)ProtocolPeer::SendReliable(*client_, {fbb.GetBufferPointer(), fbb.GetSize()});
  spdlog::info("attached to the relay as a PhyS worker");
}

void PhysicsWorker::OnOtherMessage(const schema::ControlMessage& msg) {
  auto room_of = [this](uint32_t handle) -> RoomPhysics* {
    auto it = rooms_.find(handle);
    return it == rooms_.end() ? nullptr : it->second.physics.get();
  };
  switch (msg.body_type()) {
    case schema::Body::WorkerAssign: {
      const auto* m = msg.body_as_WorkerAssign();
      physics::PhysicsConfig c = config_;
      if (m->fixed_dt() > 0 && m->fixed_dt() < 1) c.fixed_dt = m->fixed_dt();
      rooms_[m->room()].physics = std::make_unique<RoomPhysics>(c, now_);
      spdlog::info("room handle {} assigned ({} rooms)", m->room(), rooms_.size());
      break;
    }
    case schema::Body::WorkerUnassign:
      rooms_.erase(msg.body_as_WorkerUnassign()->room());
      break;
    case schema::Body::WorkerAdd: {
      const auto* m = msg.body_as_WorkerAdd();
      RoomPhysics* room = room_of(m->room());
      if (room == nullptr || m->container() == nullptr) break;
      Status added = room->Add(*m->container(), static_cast<PhysicsRole>(m->role()));
      if (!added.ok()) {
        spdlog::warn("entity {} not added: {}", m->container()->entity_id(), added.ToString());
      }
      break;
    }
    case schema::Body::WorkerRemove: {
      const auto* m = msg.body_as_WorkerRemove();
      if (RoomPhysics* room = room_of(m->room())) room->Remove(m->entity_id());
      break;
    }
    case schema::Body::WorkerDrive: {
      const auto* m = msg.body_as_WorkerDrive();
      if (RoomPhysics* room = room_of(m->room())) ApplyWorkerDrive(*m, *room, now_);
      break;
    }
    case schema::Body::WorkerGrab: {
      const auto* m = msg.body_as_WorkerGrab();
      if (RoomPhysics* room = room_of(m->room())) room->RequestGrab(m->entity_id(), m->hand_id(), !m->force());
      break;
    }
    case schema::Body::WorkerRelease: {
      const auto* m = msg.body_as_WorkerRelease();
      if (RoomPhysics* room = room_of(m->room())) (void)room->Release(m->entity_id());
      break;
    }
    case schema::Body::WorkerRestore: {
      const auto* m = msg.body_as_WorkerRestore();
      RoomPhysics* room = room_of(m->room());
      if (room != nullptr && m->nodes() != nullptr) {
        restore_nodes_.clear();
        for (const schema::Vec3* v : *m->nodes()) restore_nodes_.push_back({v->x(), v->y(), v->z()});
        Status st = room->RestoreSoftBody(m->entity_id(), m->first_node(), restore_nodes_);
        if (!st.ok()) spdlog::warn("soft body {} not restored: {}", m->entity_id(), st.ToString());
        break;
      }
      if (room == nullptr || m->pose() == nullptr) break;
      Vec3f lin = m->linear() ? Vec3f{m->linear()->x(), m->linear()->y(), m->linear()->z()} : Vec3f{};
      Vec3f ang = m->angular() ? Vec3f{m->angular()->x(), m->angular()->y(), m->angular()->z()} : Vec3f{};
      room->Restore(m->entity_id(), FromPose(*m->pose()), lin, ang);
      break;
    }
    default:
      break;
  }
}

void PhysicsWorker::SendStates(uint32_t handle, const std::vector<RoomPhysics::MovedBody>& bodies,
                               double now) {
  size_t first = 0;
  while (first < bodies.size()) {
    size_t n = 0;
    size_t size = EncodeWorkerStates(handle, bodies, first, payload_, &n);
    if (size == 0) break;
    (void)ProtocolPeer::SendUnreliable(*client_, {payload_.data(), size}, now);
    first += n;
  }
}

void PhysicsWorker::Update(double now) {
  now_ = now;
  if (client_ == nullptr || client_->state() != ClientState::kConnected) return;
  for (auto& [handle, room] : rooms_) {
    room.physics->Advance(now, &out_);
    steps_ += static_cast<uint64_t>(out_.steps);
    SendStates(handle, out_.moved, now);
    for (const RoomPhysics::SoftNodes& soft : out_.soft) {
      uint32_t first = 0;
      while (first < soft.nodes.size()) {
        uint32_t n = 0;
        size_t size = EncodeWorkerSoftChunk(handle, soft.id, soft.nodes, first, payload_, &n);
        if (size == 0) break;
        (void)ProtocolPeer::SendUnreliable(*client_, {payload_.data(), size}, now);
        first += n;
      }
    }
    if (now - room.last_refresh >= 1.0) {
      room.last_refresh = now;
      room.physics->SnapshotSimulated(&snapshot_);
      SendStates(handle, snapshot_, now);
    }
    if (!out_.events.empty() || !out_.grabs.empty() || now - room.last_report >= 0.2) {
      room.last_report = now;
      flatbuffers::FlatBufferBuilder fbb(256);
      std::vector<flatbuffers::Offset<schema::PhysicsEvent>> events;
      for (const physics::PhysicsEvent& ev : out_.events) {
        events.push_back(schema::CreatePhysicsEvent(fbb, KindOf(ev.type), ev.entity_a, ev.entity_b));
      }
      std::vector<flatbuffers::Offset<schema::WorkerGrabResult>> grabs;
      for (const RoomPhysics::GrabResult& g : out_.grabs) {
        grabs.push_back(schema::CreateWorkerGrabResultDirect(fbb, g.entity, g.hand, g.ok, g.detail.c_str()));
      }
      FinishControl(fbb, schema::CreateWorkerResult(fbb, handle, fbb.CreateVector(events),
                                                    fbb.CreateVector(grabs)));
      (void)ProtocolPeer::SendReliable(*client_, {fbb.GetBufferPointer(), fbb.GetSize()});
    }
  }
}

}  // namespace edgephys
