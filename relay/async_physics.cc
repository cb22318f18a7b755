#include "relay/async_physics.h"

#include <pthread.h>
#include <sched.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <algorithm>
#include <utility>

namespace edgephys {

void StepClock::Record(double now, int steps, float fixed_dt) {
  // As RoomPhysics::Advance: elapsed = max(0, now - time_), time_ = now; then as
  // PhysicsWorld::Advance: accumulate, one fixed_dt per step run, drop a backlog.
  const double elapsed = std::max(0.0, now - fed);
  fed = now;
  if (!(elapsed > 0)) return;
  acc += elapsed;
  for (int i = 0; i < steps; ++i) acc -= fixed_dt;
  if (acc >= fixed_dt) acc = 0;
}

void RealtimeMeter::Record(double now, double simulated) {
  simulated_ += simulated;
  const double wall = now - start_;
  if (wall >= kWindowSeconds) {
    value_ = simulated_ / wall;
    start_ = now;
    simulated_ = 0;
  } else if (wall < 0) {  // the clock went back: start over
    start_ = now;
    simulated_ = 0;
  }
}

void MergeStepOutput(RoomPhysics::StepOutput* into, RoomPhysics::StepOutput* from,
                     std::unordered_map<uint32_t, size_t>* index) {
  if (index->size() != into->moved.size()) {
    index->clear();
    for (size_t i = 0; i < into->moved.size(); ++i) (*index)[into->moved[i].state.entity_id] = i;
  }
  for (const RoomPhysics::MovedBody& m : from->moved) {
    auto [it, inserted] = index->try_emplace(m.state.entity_id, into->moved.size());
    if (inserted) {
      into->moved.push_back(m);
    } else {
      into->moved[it->second] = m;
    }
  }
  for (RoomPhysics::SoftNodes& part : from->soft) {
    auto same = std::find_if(into->soft.begin(), into->soft.end(), [&](const auto& s) {
      return s.id == part.id && s.first == part.first;
    });
    if (same == into->soft.end()) {
      into->soft.push_back(std::move(part));
    } else {
      std::swap(*same, part);
    }
  }
  into->events.insert(into->events.end(), from->events.begin(), from->events.end());
  for (RoomPhysics::GrabResult& g : from->grabs) into->grabs.push_back(std::move(g));
  into->steps += from->steps;
  into->step_seconds += from->step_seconds;
  if (from->state_time >= 0) into->state_time = from->state_time;
}

// --- PhysicsAdmission --------------------------------------------------------------------------

namespace {

// RoomPhysics' test for "mirror as kinematic" (its IsDynamic).
bool MirroredAsKinematic(const schema::Container& c, PhysicsRole role) {
  const schema::RigidBody* rb = c.rigid_body();
  return role == PhysicsRole::kMirrored && rb != nullptr && !rb->kinematic() && rb->mass() > 0;
}

// Whether PhysicsWorld builds a rigid body for `c` (body_builder.cc) — as it is, or rebuilt
// kinematic without a soft body (`as_kinematic`, a mirrored dynamic body): never for soft
// bodies; always for dynamic bodies; else when a collider is solid (not a trigger).
bool HasRigidBody(const schema::Container& c, bool as_kinematic) {
  if (!as_kinematic) {
    if (c.soft_body() != nullptr) return false;
    const schema::RigidBody* rb = c.rigid_body();
    const bool kinematic =
        rb != nullptr &&
        (rb->kinematic() || (c.flags() & static_cast<uint32_t>(schema::EntityFlags::Kinematic)));
    if (rb != nullptr && !kinematic && rb->mass() > 0) return true;
  }
  if (c.colliders() == nullptr) return false;
  for (const schema::Collider* col : *c.colliders()) {
    if (!col->is_trigger()) return true;
  }
  return false;
}

// PhysicsWorld::AddEntity's Status message for a refusal (RejectionStatus).
std::string_view RejectionMessage(physics::InvalidReason why) {
  using R = physics::InvalidReason;
  if (why == R::kDuplicateId) return "duplicate entity id";
  if (why == R::kTooManyNodes || why == R::kTooManyColliders) {
    return "container over the configured limits";
  }
  return "invalid container";
}

}  // namespace

PhysicsRole PhysicsAdmission::RoleOf(uint32_t id) const {
  auto it = known_.find(id);
  return it == known_.end() ? PhysicsRole::kNone : it->second.role;
}

void PhysicsAdmission::Added(const schema::Container& c, PhysicsRole role) {
  known_[c.entity_id()] = Known{role, HasRigidBody(c, MirroredAsKinematic(c, role))};
}

physics::InvalidReason PhysicsAdmission::Check(const schema::Container& added,
                                               schema::ContainerT* copy) {
  using R = physics::InvalidReason;
  // The checks against the world's entities, in PhysicsWorld's order (ValidateIds)...
  const uint32_t id = added.entity_id();
  if (id == 0) return R::kZeroId;
  if (known_.count(id) != 0) return R::kDuplicateId;
  const uint32_t parent = added.parent_id();
  if (parent != 0 && (parent == id || known_.count(parent) == 0)) return R::kUnknownParent;
  // ... then every component check, against an empty world: without the parent and the joint
  // partners, which it does not have ...
  if (validator_ == nullptr) validator_ = std::make_unique<physics::PhysicsWorld>(config_);
  bool partners = false;
  if (added.joints() != nullptr) {
    for (const schema::Joint* j : *added.joints()) partners |= j->connected_entity() != 0;
  }
  R reason;
  if (parent == 0 && !partners) {
    reason = validator_->Validate(added);
  } else {
    copy->parent_id = 0;
    for (auto& j : copy->joints) j->connected_entity = 0;
    flatbuffers::FlatBufferBuilder fbb(1024);
    fbb.Finish(schema::Container::Pack(fbb, copy));
    reason = validator_->Validate(*flatbuffers::GetRoot<schema::Container>(fbb.GetBufferPointer()));
  }
  if (reason != R::kNone) return reason;
  // ... and the partners: existing entities with a rigid body.
  if (partners) {
    for (const schema::Joint* j : *added.joints()) {
      const uint32_t other = j->connected_entity();
      if (other == 0) continue;
      auto it = known_.find(other);
      if (other == id || it == known_.end() || !it->second.has_body) return R::kUnknownJointTarget;
    }
  }
  return R::kNone;
}

Status PhysicsAdmission::Admit(const schema::Container& c, PhysicsRole role,
                               PhysicsCommand* command) {
  const bool converted = MirroredAsKinematic(c, role);
  if (!converted && role == PhysicsRole::kMirrored && c.soft_body() != nullptr) {
    return Status(StatusCode::kInvalidArgument, "soft body not offloaded",
                  "a soft body must be offloaded (Offloaded flag) to be simulated");
  }
  schema::ContainerT copy;
  c.UnPackTo(&copy);
  if (converted) {
    copy.rigid_body->kinematic = true;
    copy.soft_body.reset();
  }
  flatbuffers::FlatBufferBuilder fbb(1024);
  fbb.Finish(schema::Container::Pack(fbb, &copy));
  const auto* added = flatbuffers::GetRoot<schema::Container>(fbb.GetBufferPointer());
  const physics::InvalidReason why = Check(*added, &copy);
  if (why != physics::InvalidReason::kNone) {
    ++rejected_;
    return Status(StatusCode::kInvalidArgument, "invalid physics components",
                  "physics: " + std::string(RejectionMessage(why)) + " (reason " +
                      std::to_string(static_cast<int>(why)) + ")");
  }
  known_[added->entity_id()] = Known{role, HasRigidBody(*added, false)};
  command->kind = PhysicsCommand::Kind::kAdd;
  command->role = role;
  command->id = added->entity_id();
  command->container = fbb.Release();
  return Status::Ok();
}

// --- AsyncPhysicsRoom --------------------------------------------------------------------------

AsyncPhysicsRoom::AsyncPhysicsRoom(AsyncPhysicsPool* pool, std::unique_ptr<RoomPhysics> physics,
                                   const physics::PhysicsConfig& config, const StepClock& clock)
    : pool_(pool),
      fixed_dt_(config.fixed_dt),
      max_substeps_(std::max(1, config.max_substeps)),
      target_(clock.fed),
      next_due_(clock.next_due(config.fixed_dt)),
      counters_(physics->counters()),
      physics_(std::move(physics)),
      clock_(clock) {}

void AsyncPhysicsRoom::Post(PhysicsCommand&& command) {
  std::lock_guard<std::mutex> lock(mu_);
  if (command.kind == PhysicsCommand::Kind::kDrive) {
    // Only the last pose before a step matters; drives of different entities commute.
    for (size_t i = drive_run_; i < inbox_.size(); ++i) {
      if (inbox_[i].id == command.id) {
        inbox_[i].state = command.state;
        inbox_[i].time = command.time;
        return;
      }
    }
    inbox_.push_back(std::move(command));
    return;
  }
  inbox_.push_back(std::move(command));
  drive_run_ = inbox_.size();
}

bool AsyncPhysicsRoom::WantsRun() const {
  return !closed_ && finished_.size() < kMaxFinished && (!inbox_.empty() || target_ >= next_due_);
}

void AsyncPhysicsRoom::Advance(double now, Outputs* finished, Outputs* used,
                               physics::PhysicsCounters* counters) {
  bool schedule = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    target_ = now;
    for (auto& out : *used) spare_.push_back(std::move(out));
    used->clear();
    for (auto& out : finished_) finished->push_back(std::move(out));
    finished_.clear();
    *counters = counters_;
    if (!scheduled_ && WantsRun()) schedule = scheduled_ = true;
  }
  if (schedule) pool_->Schedule(this);
}

void AsyncPhysicsRoom::Close() {
  bool schedule = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    closed_ = true;
    inbox_.clear();
    drive_run_ = 0;
    if (!scheduled_) schedule = scheduled_ = true;
  }
  // Idle: a physics thread frees it. Queued or running: the thread that has it frees it.
  if (schedule) pool_->Schedule(this);
}

void AsyncPhysicsRoom::Apply(PhysicsCommand& c) {
  using K = PhysicsCommand::Kind;
  switch (c.kind) {
    case K::kAdd: {
      const auto* container = flatbuffers::GetRoot<schema::Container>(c.container.data());
      Status st = physics_->Add(*container, c.role);
      if (!st.ok()) {
        // The relay validated it against the same rules: a mismatch is a bug, not input.
        spdlog::error("PhyS: entity {} accepted by the relay was refused by its world: {}", c.id,
                      st.ToString());
      }
      c.container = flatbuffers::DetachedBuffer();
      break;
    }
    case K::kRemove: physics_->Remove(c.id); break;
    case K::kDrive: physics_->Drive(c.id, c.state, c.time); break;
    case K::kGrab: physics_->RequestGrab(c.id, c.hand, !c.force); break;
    case K::kRelease: (void)physics_->Release(c.id); break;
    case K::kRestore: physics_->Restore(c.id, c.state, c.linear, c.angular); break;
    case K::kRestoreNodes: {
      Status st = physics_->RestoreSoftBody(c.id, 0, c.nodes);
      if (!st.ok()) spdlog::warn("PhyS: soft body {} not restored: {}", c.id, st.ToString());
      c.nodes = {};
      break;
    }
  }
}

AsyncPhysicsRoom::Run AsyncPhysicsRoom::RunOnce() {
  std::unique_ptr<StepOutput> out;
  double target;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (closed_) return Run::kClosed;
    work_.swap(inbox_);
    drive_run_ = 0;
    target = target_;
    if (!spare_.empty()) {
      out = std::move(spare_.back());
      spare_.pop_back();
    }
  }
  if (out == nullptr) out = std::make_unique<StepOutput>();
  for (PhysicsCommand& c : work_) Apply(c);
  work_.clear();

  // Simulation time runs with the relay's clock, less the backlog dropped: at most one step's
  // worth when steps cost more than real time (catching up is hopeless and would only make the
  // room's output burstier), else up to max_substeps (scheduling jitter).
  double sim = target - offset_;
  const double cap = static_cast<double>(slow_ ? 1 : max_substeps_) * fixed_dt_;
  if (sim - clock_.fed > cap) {
    offset_ += sim - clock_.fed - cap;
    sim = clock_.fed + cap;
  }
  physics_->Advance(sim, out.get());
  clock_.Record(sim, out->steps, fixed_dt_);
  // The world's time after its last step (the accumulator holds what is not yet stepped), on
  // the relay's clock.
  if (out->steps > 0) out->state_time = offset_ + clock_.fed - clock_.acc;
  if (out->steps > 0) slow_ = out->step_seconds > out->steps * static_cast<double>(fixed_dt_);
  const physics::PhysicsCounters counters = physics_->counters();

  std::lock_guard<std::mutex> lock(mu_);
  const bool has_output = out->steps > 0 || !out->grabs.empty() || !out->events.empty() ||
                          !out->moved.empty() || !out->soft.empty();
  (has_output ? finished_ : spare_).push_back(std::move(out));
  counters_ = counters;
  next_due_ = offset_ + clock_.next_due(fixed_dt_);
  if (closed_) return Run::kClosed;
  if (WantsRun()) return Run::kRequeue;  // scheduled_ stays set
  scheduled_ = false;
  return Run::kIdle;
}

// --- AsyncPhysicsPool --------------------------------------------------------------------------

namespace {

// Lowers the calling thread's priority by `nice` (Linux: setpriority on the thread id).
bool LowerThisThreadsPriority(int nice) {
  errno = 0;
  const int base = getpriority(PRIO_PROCESS, 0);
  if (base == -1 && errno != 0) return false;
  const int target = std::min(19, base + nice);
  if (setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), target) != 0) {
    spdlog::warn("physics thread: setpriority({}) failed: {}", target, std::strerror(errno));
    return false;
  }
  return true;
}

// Puts the calling thread in SCHED_IDLE (Linux: runs only when a core has nothing else of
// SCHED_OTHER to run; no privilege needed to lower one's own policy).
bool MakeThisThreadIdle() {
  sched_param param{};
  if (sched_setscheduler(static_cast<pid_t>(gettid()), SCHED_IDLE, &param) != 0) {
    spdlog::warn("physics thread: SCHED_IDLE failed: {}", std::strerror(errno));
    return false;
  }
  return true;
}

}  // namespace

AsyncPhysicsPool::AsyncPhysicsPool(size_t threads, int nice, bool idle)
    : nice_(std::max(0, nice)), sched_idle_(idle) {
  for (size_t i = 0; i < std::max<size_t>(1, threads); ++i) {
    threads_.emplace_back([this] {
      if (sched_idle_ ? MakeThisThreadIdle() : nice_ > 0 && LowerThisThreadsPriority(nice_)) {
        reniced_.fetch_add(1);
      }
      ThreadLoop();
    });
    pthread_setname_np(threads_.back().native_handle(), "edgephys-physs");
  }
}

AsyncPhysicsPool::~AsyncPhysicsPool() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : threads_) t.join();
  // Every link is gone (closed rooms) or must not be used again; no thread runs any more.
  for (AsyncPhysicsRoom* room : rooms_) delete room;
}

AsyncPhysicsRoom* AsyncPhysicsPool::Adopt(std::unique_ptr<RoomPhysics> physics,
                                          const physics::PhysicsConfig& config,
                                          const StepClock& clock) {
  auto* room = new AsyncPhysicsRoom(this, std::move(physics), config, clock);
  std::lock_guard<std::mutex> lock(mu_);
  rooms_.insert(room);
  return room;
}

void AsyncPhysicsPool::Schedule(AsyncPhysicsRoom* room) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    ready_.push_back(room);
  }
  wake_.notify_one();
}

void AsyncPhysicsPool::WaitIdle() {
  std::unique_lock<std::mutex> lock(mu_);
  idle_.wait(lock, [this] { return stop_ || (ready_.empty() && running_ == 0); });
}

void AsyncPhysicsPool::ThreadLoop() {
  std::unique_lock<std::mutex> lock(mu_);
  for (;;) {
    wake_.wait(lock, [this] { return stop_ || !ready_.empty(); });
    if (stop_) return;
    AsyncPhysicsRoom* room = ready_.front();
    ready_.pop_front();
    ++running_;
    lock.unlock();
    const AsyncPhysicsRoom::Run run = room->RunOnce();
    if (run == AsyncPhysicsRoom::Run::kClosed) delete room;  // its world is freed here, too
    lock.lock();
    --running_;
    if (run == AsyncPhysicsRoom::Run::kClosed) rooms_.erase(room);
    // At the back: the rooms queued meanwhile go first. This thread, awake, takes the front.
    if (run == AsyncPhysicsRoom::Run::kRequeue) ready_.push_back(room);
    if (ready_.empty() && running_ == 0) idle_.notify_all();
  }
}

}  // namespace edgephys
