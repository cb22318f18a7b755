#include "physics_backend/room_physics.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>

namespace edgephys {
namespace {

Eigen::Quaternionf ToEigen(const Quatf& q) { return Eigen::Quaternionf(q.w, q.x, q.y, q.z); }
Eigen::Vector3f ToEigen(const Vec3f& v) { return Eigen::Vector3f(v.x, v.y, v.z); }
Quatf FromEigen(const Eigen::Quaternionf& q) { return {q.x(), q.y(), q.z(), q.w()}; }
Vec3f FromEigen(const Eigen::Vector3f& v) { return {v.x(), v.y(), v.z()}; }

bool IsDynamic(const schema::Container& c) {
  const schema::RigidBody* rb = c.rigid_body();
  return rb != nullptr && !rb->kinematic() && rb->mass() > 0;
}

}  // namespace

RoomPhysics::RoomPhysics(const physics::PhysicsConfig& config, double now)
    : world_(config), time_(now) {}

PhysicsRole RoomPhysics::RoleOf(const schema::Container& c) {
  const bool offloaded = (c.flags() & static_cast<uint32_t>(schema::EntityFlags::Offloaded)) != 0;
  if (offloaded && (IsDynamic(c) || c.soft_body() != nullptr)) return PhysicsRole::kSimulated;
  const bool has_colliders = c.colliders() != nullptr && c.colliders()->size() > 0;
  if (has_colliders || c.rigid_body() != nullptr || c.soft_body() != nullptr) {
    return PhysicsRole::kMirrored;
  }
  // An offloaded entity without physics (a parent): kept as a transform-only node so the
  // hierarchy under it is replicated by PhyS.
  if (offloaded) return PhysicsRole::kMirrored;
  return PhysicsRole::kNone;
}

Status RoomPhysics::Add(const schema::Container& c, PhysicsRole role) {
  physics::InvalidReason reason = physics::InvalidReason::kNone;
  Status st;
  if (role == PhysicsRole::kMirrored && IsDynamic(c)) {
    // Mirror a locally simulated body as kinematic: its owner is the authority.
    schema::ContainerT copy;
    c.UnPackTo(&copy);
    copy.rigid_body->kinematic = true;
    copy.soft_body.reset();
    flatbuffers::FlatBufferBuilder fbb(512);
    fbb.Finish(schema::Container::Pack(fbb, &copy));
    st = world_.AddEntity(*flatbuffers::GetRoot<schema::Container>(fbb.GetBufferPointer()), &reason);
  } else if (role == PhysicsRole::kMirrored && c.soft_body() != nullptr) {
    return Status::InvalidArgument("soft body not offloaded",
                                   "a soft body must be offloaded (Offloaded flag) to be simulated");
  } else {
    st = world_.AddEntity(c, &reason);
  }
  if (!st.ok()) {
    return Status::InvalidArgument("invalid physics components",
                                   "physics: " + std::string(st.message()) + " (reason " +
                                       std::to_string(static_cast<int>(reason)) + ")");
  }
  roles_[c.entity_id()] = role;
  if (c.soft_body() != nullptr) soft_.insert(c.entity_id());
  return Status::Ok();
}

void RoomPhysics::Remove(uint32_t id) {
  if (roles_.erase(id) == 0) return;
  soft_.erase(id);
  (void)world_.RemoveEntity(id);
  holds_.erase(id);
  driven_.erase(id);
  for (auto it = holds_.begin(); it != holds_.end();) {
    it = it->second.hand == id ? holds_.erase(it) : std::next(it);
  }
  for (auto it = hovering_.begin(); it != hovering_.end();) {
    it = (it->first == id || it->second == id) ? hovering_.erase(it) : std::next(it);
  }
}

void RoomPhysics::Drive(uint32_t id, const EntityState& s, double time) {
  auto role = roles_.find(id);
  if (role == roles_.end() || role->second != PhysicsRole::kMirrored) return;
  DrivenPoses& poses = driven_[id];
  if (!poses.pending) pending_driven_.push_back(id);
  poses.pending = true;
  poses.time = time;
  poses.state = s;
  (void)world_.MoveToTransform(id, s.position, s.rotation);
  const Eigen::Quaternionf hand_rot = ToEigen(s.rotation).normalized();
  const Eigen::Vector3f hand_pos = ToEigen(s.position);
  for (const auto& [entity, hold] : holds_) {
    if (hold.hand != id) continue;
    Eigen::Vector3f pos = hand_pos + hand_rot * ToEigen(hold.offset_position);
    Eigen::Quaternionf rot = hand_rot * ToEigen(hold.offset_rotation);
    (void)world_.MoveToTransform(entity, FromEigen(pos), FromEigen(rot.normalized()));
  }
}

Status RoomPhysics::Grab(uint32_t entity, uint32_t hand, bool require_hover) {
  auto role = roles_.find(entity);
  if (role == roles_.end() || role->second != PhysicsRole::kSimulated) {
    return Status::PermissionDenied("not simulated", "only PhyS-simulated entities can be grabbed");
  }
  if (auto held = holds_.find(entity); held != holds_.end() && held->second.hand != hand) {
    return Status::PermissionDenied("held", "already held by another hand");
  }
  if (require_hover && hovering_.count({hand, entity}) == 0) {
    return Status::PermissionDenied("not hovering", "the hand's trigger does not hover the entity");
  }
  Status st = world_.Grab(entity, hand);
  if (!st.ok()) {
    return Status::PermissionDenied("refused by PhyS", std::string(st.message()));
  }
  EntityState hand_state, entity_state;
  (void)world_.GetState(hand, &hand_state);
  (void)world_.GetState(entity, &entity_state);
  const Eigen::Quaternionf inv = ToEigen(hand_state.rotation).normalized().conjugate();
  Hold hold;
  hold.hand = hand;
  hold.offset_position =
      FromEigen(inv * (ToEigen(entity_state.position) - ToEigen(hand_state.position)));
  hold.offset_rotation = FromEigen((inv * ToEigen(entity_state.rotation)).normalized());
  holds_[entity] = hold;
  return Status::Ok();
}

void RoomPhysics::CommitDrivenPoses() {
  for (uint32_t id : pending_driven_) {
    auto it = driven_.find(id);
    if (it == driven_.end() || !it->second.pending) continue;  // removed since
    DrivenPoses& d = it->second;
    d.history.Add(d.time, d.state.position, d.state.rotation);
    d.pending = false;
  }
  pending_driven_.clear();
}

Status RoomPhysics::Release(uint32_t entity) {
  auto held = holds_.find(entity);
  if (held == holds_.end()) return Status(StatusCode::kNotFound, "not held");
  const uint32_t hand = held->second.hand;
  holds_.erase(held);
  Status st = world_.Release(entity);
  const float window = world_.config().release_velocity_window_s;
  auto poses = driven_.find(hand);
  if (!st.ok() || !(window > 0) || poses == driven_.end()) return st;
  // The hand's poses up to now: those committed at each Advance, and the one since.
  physics::PoseHistory history = poses->second.history;
  if (poses->second.pending) {
    history.Add(poses->second.time, poses->second.state.position, poses->second.state.rotation);
  }
  Vec3f v_hand, w_hand;
  double t;
  Vec3f hand_pos;
  Quatf hand_rot;
  if (!history.Estimate(window, &v_hand, &w_hand) || !history.Newest(&t, &hand_pos, &hand_rot)) {
    return st;
  }
  EntityState now_state;
  if (!world_.GetState(entity, &now_state).ok()) return st;
  // A point held rigidly by the hand moves at v_hand + w_hand x (its offset from the hand).
  const Eigen::Vector3f w = ToEigen(w_hand);
  Eigen::Vector3f v = ToEigen(v_hand) + w.cross(ToEigen(now_state.position) - ToEigen(hand_pos));
  Eigen::Vector3f wv = w;  // capped below, separately from the w x r above
  const physics::PhysicsConfig& c = world_.config();
  if (v.norm() > c.grab_max_speed) v *= c.grab_max_speed / v.norm();
  if (wv.norm() > c.grab_max_angular_speed) wv *= c.grab_max_angular_speed / wv.norm();
  return world_.SetVelocity(entity, FromEigen(v), FromEigen(wv));
}

uint32_t RoomPhysics::HolderOf(uint32_t entity) const {
  auto it = holds_.find(entity);
  return it == holds_.end() ? 0 : it->second.hand;
}

void RoomPhysics::Restore(uint32_t id, const EntityState& state, const Vec3f& linear,
                          const Vec3f& angular) {
  (void)world_.SetTransform(id, state.position, state.rotation);
  (void)world_.SetVelocity(id, linear, angular);
}

void RoomPhysics::SnapshotSimulated(std::vector<MovedBody>* out) const {
  out->clear();
  for (const auto& [id, role] : roles_) {
    if (role != PhysicsRole::kSimulated || soft_.count(id) != 0) continue;
    MovedBody m;
    if (!world_.GetState(id, &m.state).ok()) continue;
    m.state.entity_id = id;
    (void)world_.GetVelocity(id, &m.linear, &m.angular);
    out->push_back(m);
  }
}

void RoomPhysics::RequestGrab(uint32_t entity, uint32_t hand, bool require_hover) {
  GrabResult r;
  r.entity = entity;
  r.hand = hand;
  Status st = Grab(entity, hand, require_hover);
  r.ok = st.ok();
  if (!st.ok()) r.detail = std::string(st.reason());
  pending_grabs_.push_back(std::move(r));
}

void RoomPhysics::Advance(double now, StepOutput* out) {
  out->Clear();
  out->grabs.swap(pending_grabs_);
  CommitDrivenPoses();
  auto start = std::chrono::steady_clock::now();
  // The world accumulates elapsed time and runs whole fixed steps (dropping a backlog beyond
  // max_substeps rather than replaying it).
  out->steps = world_.Advance(std::max(0.0, now - time_));
  time_ = now;
  if (out->steps == 0) return;
  out->step_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  world_.DrainEvents(&out->events);
  for (const physics::PhysicsEvent& ev : out->events) {
    if (ev.type == physics::PhysicsEventType::kTriggerEnter) hovering_.insert({ev.entity_a, ev.entity_b});
    if (ev.type == physics::PhysicsEventType::kTriggerExit) hovering_.erase({ev.entity_a, ev.entity_b});
  }
  world_.CollectStates(&scratch_states_);
  for (const EntityState& s : scratch_states_) {
    auto role = roles_.find(s.entity_id);
    if (role == roles_.end() || role->second != PhysicsRole::kSimulated) continue;
    MovedBody m;
    m.state = s;
    (void)world_.GetVelocity(s.entity_id, &m.linear, &m.angular);
    out->moved.push_back(m);
    if (soft_.count(s.entity_id) != 0) {
      out->soft.emplace_back();
      out->soft.back().id = s.entity_id;
      (void)world_.GetSoftBodyNodes(s.entity_id, &out->soft.back().nodes);
      out->soft.back().total = static_cast<uint32_t>(out->soft.back().nodes.size());
    }
  }
}

}  // namespace edgephys
