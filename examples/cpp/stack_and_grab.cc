// The edgephys SDK example, in C++ over the header-only wrapper (edgephys/edgephys.hpp); the
// same program as examples/c/stack_and_grab.c (see there), plus a watcher mode:
//
//   stack_and_grab_cpp <relay host:port> <join token> <room>            # the example
//   stack_and_grab_cpp <relay host:port> <join token> <room> --watch     # a second client
//
// --watch joins the same room, keeps the latest received transform of every entity, and when
// another player leaves prints "pose <id> x y z qx qy qz qw" for each (as the example does for
// its boxes), so tests/sdk_examples_test.sh can check both saw the same poses; it prints each
// chat line (application message) it receives as "chat from <player>: <text>". It proposes
// its own "current step" when another player joins (both race with compare-and-set; the relay
// takes one) and prints "agreed step: <value> (written by player <id>)"; when an entity is
// handed to it, it prints "handoff: got entity <id>" and publishes that entity at y = 0.5.
#include <edgephys/edgephys.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <string>
#include <thread>
#include <vector>

namespace {

using edgephys::sdk::Client;
using edgephys::sdk::Int64Value;
using edgephys::sdk::Property;

[[noreturn]] void Fail(const std::string& why) {
  std::printf("FAIL: %s (%s)\n", why.c_str(), Client::LastError().c_str());
  std::exit(1);
}
void Check(edgephys_status st, const char* what) {
  if (st != EDGEPHYS_OK) Fail(std::string(what) + ": " + edgephys_status_name(st));
}

const char* EventName(uint32_t type) {
  switch (type) {
    case EDGEPHYS_EVENT_COLLISION_ENTER: return "collision_enter";
    case EDGEPHYS_EVENT_COLLISION_EXIT: return "collision_exit";
    case EDGEPHYS_EVENT_TRIGGER_ENTER: return "trigger_enter";
    case EDGEPHYS_EVENT_TRIGGER_EXIT: return "trigger_exit";
    case EDGEPHYS_EVENT_GRABBED: return "grabbed";
    case EDGEPHYS_EVENT_RELEASED: return "released";
    case EDGEPHYS_EVENT_GUARD_RESET: return "guard_reset";
    default: return nullptr;
  }
}

void PrintPose(uint32_t id, const edgephys_transform& t) {
  std::printf("pose %u %.6f %.6f %.6f %.6f %.6f %.6f %.6f\n", id, t.position.x, t.position.y,
              t.position.z, t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w);
}

class Example {
 public:
  explicit Example(Client* client) : c_(*client) {}

  // One frame: update, drain events. `on_event` sees every event first.
  void Pump(const std::function<void(const edgephys_event&)>& on_event = {}) {
    Check(c_.Update(edgephys_now_s()), "update");
    edgephys_event ev;
    while (c_.Poll(&ev)) {
      if (on_event) on_event(ev);
      if (ev.type == EDGEPHYS_EVENT_CONNECTED) connected_ = true;
      if (ev.type == EDGEPHYS_EVENT_JOINED) joined_ = true;
      if (ev.type == EDGEPHYS_EVENT_PLAYER_JOINED) other_player = ev.player_id;
      if (ev.type == EDGEPHYS_EVENT_REJECTED) Fail("rejected");
      if (ev.type == EDGEPHYS_EVENT_DISCONNECTED) Fail("disconnected");
      if (ev.type == EDGEPHYS_EVENT_ERROR) std::printf("error reason %u entity %u: %s\n", ev.code, ev.entity_id, ev.detail);
      if (const char* name = EventName(ev.type)) {
        std::printf("event %s %u %u\n", name, ev.entity_id, ev.other_id);
        events_.push_back(ev);
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  void RunFor(double s) {
    for (double end = edgephys_now_s() + s; edgephys_now_s() < end;) Pump();
  }
  void WaitFor(const std::function<bool()>& done, double timeout_s, const char* what) {
    for (double end = edgephys_now_s() + timeout_s; !done(); Pump()) {
      if (edgephys_now_s() > end) Fail(what);
    }
  }
  void ConnectAndJoin(const char* relay, const char* token, const char* room) {
    Check(c_.Connect(relay, token, edgephys_now_s()), "connect");
    WaitFor([&] { return connected_; }, 5, "no connection");
    Check(c_.Join(room), "join");
    WaitFor([&] { return joined_; }, 5, "no join");
  }
  int Find(uint32_t type, uint32_t a, uint32_t b, int from = 0) const {
    for (int i = from; i < static_cast<int>(events_.size()); ++i) {
      const auto& e = events_[i];
      if (e.type == type && e.entity_id == a && (b == 0 || e.other_id == b)) return i;
    }
    return -1;
  }
  bool State(uint32_t id, edgephys_transform* t) {
    edgephys_entity e;
    if (!c_.Entity(id, &e) || !e.has_state) return false;
    *t = e.transform;
    return true;
  }
  bool Settled(const std::vector<uint32_t>& ids) {
    std::vector<edgephys_transform> before(ids.size()), after(ids.size());
    for (size_t i = 0; i < ids.size(); ++i) if (!State(ids[i], &before[i])) return false;
    RunFor(0.5);
    for (size_t i = 0; i < ids.size(); ++i) {
      if (!State(ids[i], &after[i])) return false;
      const float dx = after[i].position.x - before[i].position.x, dy = after[i].position.y - before[i].position.y,
                  dz = after[i].position.z - before[i].position.z;
      if (std::sqrt(dx * dx + dy * dy + dz * dz) > 0.001f) return false;
    }
    return true;
  }
  void WaitSettled(const std::vector<uint32_t>& ids) {
    for (double end = edgephys_now_s() + 10; !Settled(ids);) {
      if (edgephys_now_s() > end) Fail("the boxes did not settle");
      Pump();
    }
  }
  uint32_t Spawn(const edgephys_spawn_desc& d) {
    const uint32_t id = c_.Spawn(d);
    if (id == 0) Fail("spawn");
    return id;
  }
  void Publish(uint32_t id, float x, float y, float z) { Check(c_.Publish(id, {{x, y, z}, {0, 0, 0, 1}}), "publish"); }

  uint32_t other_player = 0;  // the latest other player who joined (0: none yet)
  Client& c_;
  bool connected_ = false, joined_ = false;
  std::vector<edgephys_event> events_;
};

int Watch(Client& client, const char* relay, const char* token, const char* room) {
  Example ex(&client);
  std::map<uint32_t, edgephys_transform> latest;
  bool someone_left = false, proposed = false, agreed = false;
  uint32_t self = 0, baton = 0;
  ex.ConnectAndJoin(relay, token, room);
  self = client.Info().player_id;
  std::printf("watching\n");
  std::fflush(stdout);
  const double end = edgephys_now_s() + 60;
  while (!someone_left && edgephys_now_s() < end) {
    ex.Pump([&](const edgephys_event& ev) {
      if (ev.type == EDGEPHYS_EVENT_SPAWNED || ev.type == EDGEPHYS_EVENT_STATE) latest[ev.entity_id] = ev.transform;
      if (ev.type == EDGEPHYS_EVENT_PLAYER_LEFT) someone_left = true;
      if (ev.type == EDGEPHYS_EVENT_PLAYER_JOINED && ev.player_id != self && !proposed) {
        proposed = client.CompareAndSetProperty(0, "step", Int64Value(2), 0, EDGEPHYS_AUTHORITY_ANYONE) != 0;
      }
      Property p;
      if ((ev.type == EDGEPHYS_EVENT_PROPERTY_CHANGED || ev.type == EDGEPHYS_EVENT_PROPERTY_CONFLICT) &&
          std::string(ev.detail) == "step" && !agreed && client.EventProperty(&p) && p.info.version >= 1) {
        agreed = true;
        std::printf("agreed step: %lld (written by player %u)\n",
                    static_cast<long long>(p.info.value.int_value), p.info.writer);
      }
      if (ev.type == EDGEPHYS_EVENT_OWNERSHIP_CHANGED && ev.player_id == self && self != 0) {
        baton = ev.entity_id;
        std::printf("handoff: got entity %u\n", baton);
      }
      std::string text;
      if (ev.type == EDGEPHYS_EVENT_MESSAGE && client.Message(&text)) {
        std::printf("chat from %u: %s\n", ev.player_id, text.c_str());
      }
    });
    if (baton != 0) (void)client.Publish(baton, {{2, 0.5f, 0}, {0, 0, 0, 1}});
  }
  if (!someone_left) Fail("nobody left the room within 60 s");
  for (const auto& [id, t] : latest) PrintPose(id, t);
  std::printf("ok\n");
  return 0;
}

int Run(Client& client, const char* relay, const char* token, const char* room) {
  Example ex(&client);
  ex.ConnectAndJoin(relay, token, room);
  // A chat line to everyone else in the room (reliable; they get it with our player id).
  Check(client.SendMessage(EDGEPHYS_TO_OTHERS, "hello from the C++ example"), "chat");
  // A shared "current step" (a room property anyone may write): proposed with compare-and-set,
  // expected version 0 (only if nobody set it yet). Another player may propose at the same
  // time; the relay takes exactly one proposal and the other writer gets a PROPERTY_CONFLICT
  // with the winner's value, so both end on the same step.
  if (client.CompareAndSetProperty(0, "step", Int64Value(1), 0, EDGEPHYS_AUTHORITY_ANYONE) == 0) Fail("step");
  Property step;
  ex.WaitFor([&] { return client.GetProperty(0, "step", &step) && step.info.version >= 1; }, 5, "no agreed step");
  std::printf("agreed step: %lld (written by player %u)\n", static_cast<long long>(step.info.value.int_value),
              step.info.writer);

  edgephys_collider ground_box, head_sphere, trigger, box;
  edgephys_collider_init(&ground_box);
  ground_box.half_extents = {5, 0.5f, 5};
  edgephys_spawn_desc d;
  edgephys_spawn_desc_init(&d);
  d.transform.position.y = -0.5f;
  d.flags = EDGEPHYS_FLAG_OFFLOADED;
  d.colliders = &ground_box;
  d.collider_count = 1;
  const uint32_t ground = ex.Spawn(d);

  edgephys_rigid_body kinematic, dynamic;
  edgephys_rigid_body_init(&kinematic);
  kinematic.kinematic = 1;
  kinematic.mass = 0;
  edgephys_rigid_body_init(&dynamic);
  edgephys_collider_init(&head_sphere);
  head_sphere.shape = EDGEPHYS_SHAPE_SPHERE;
  head_sphere.radius = 0.1f;
  trigger = head_sphere;
  trigger.radius = 0.15f;
  trigger.is_trigger = 1;
  edgephys_spawn_desc_init(&d);
  d.transform.position = {0, 1.6f, 1};
  d.flags = EDGEPHYS_FLAG_AVATAR;
  d.rigid_body = &kinematic;
  d.colliders = &head_sphere;
  d.collider_count = 1;
  const uint32_t head = ex.Spawn(d);
  uint32_t hands[2];
  for (int h = 0; h < 2; ++h) {
    edgephys_spawn_desc_init(&d);
    d.transform.position = {h == 0 ? -0.3f : 0.3f, 1.2f, 1};
    d.flags = EDGEPHYS_FLAG_HAND;
    d.rigid_body = &kinematic;
    d.colliders = &trigger;
    d.collider_count = 1;
    hands[h] = ex.Spawn(d);
  }
  edgephys_collider_init(&box);
  box.half_extents = {0.1f, 0.1f, 0.1f};
  std::vector<uint32_t> boxes;
  for (int i = 0; i < 3; ++i) {
    edgephys_spawn_desc_init(&d);
    d.transform.position = {0, 0.3f + 0.3f * static_cast<float>(i), 0};
    d.flags = EDGEPHYS_FLAG_OFFLOADED | EDGEPHYS_FLAG_INTERACTABLE | EDGEPHYS_FLAG_REPORT_CONTACTS;
    d.rigid_body = &dynamic;
    d.colliders = &box;
    d.collider_count = 1;
    boxes.push_back(ex.Spawn(d));
  }
  std::printf("spawned ground %u head %u hands %u %u boxes %u %u %u\n", ground, head, hands[0], hands[1],
              boxes[0], boxes[1], boxes[2]);

  ex.WaitSettled(boxes);
  for (size_t i = 0; i < boxes.size(); ++i) {
    edgephys_transform t{};
    ex.State(boxes[i], &t);
    std::printf("settled box %u at %.3f %.3f %.3f\n", boxes[i], t.position.x, t.position.y, t.position.z);
    if (std::fabs(t.position.y - (0.1f + 0.2f * static_cast<float>(i))) > 0.03f) Fail("a box is not where the stack puts it");
  }

  const uint32_t top = boxes[2], below = boxes[1], hand = hands[1];
  edgephys_transform top_t{};
  ex.State(top, &top_t);
  const float y0 = top_t.position.y + 0.05f;
  ex.Publish(hand, top_t.position.x, y0, top_t.position.z);
  ex.WaitFor([&] { return ex.Find(EDGEPHYS_EVENT_TRIGGER_ENTER, hand, top) >= 0; }, 3, "the hand's trigger never reported the box");
  Check(client.Grab(top, hand), "grab");
  ex.WaitFor([&] { return ex.Find(EDGEPHYS_EVENT_GRABBED, top, hand) >= 0; }, 3, "no Grabbed event");
  const double start = edgephys_now_s();
  for (double t = 0; t < 1.0; t = edgephys_now_s() - start) {
    ex.Publish(hand, 0.6f * static_cast<float>(t), y0 + 0.4f * static_cast<float>(t), top_t.position.z);
    ex.Pump();
  }
  Check(client.Release(top), "release");
  ex.Publish(hand, 0.3f, 1.2f, 1);
  ex.WaitFor([&] { return ex.Find(EDGEPHYS_EVENT_RELEASED, top, hand) >= 0; }, 3, "no Released event");
  ex.WaitSettled(boxes);

  const int grabbed = ex.Find(EDGEPHYS_EVENT_GRABBED, top, hand);
  const int left_stack = ex.Find(EDGEPHYS_EVENT_COLLISION_EXIT, below, top);
  const int released = ex.Find(EDGEPHYS_EVENT_RELEASED, top, hand);
  int landed = -1;
  for (int i = released + 1; i < static_cast<int>(ex.events_.size()) && landed < 0; ++i) {
    const auto& e = ex.events_[i];
    if (e.type == EDGEPHYS_EVENT_COLLISION_ENTER && (e.entity_id == top || e.other_id == top)) landed = i;
  }
  if (!(grabbed >= 0 && left_stack > grabbed && released > left_stack && landed > released)) {
    std::printf("FAIL: event order grabbed %d left_stack %d released %d landed %d\n", grabbed, left_stack, released, landed);
    return 1;
  }
  edgephys_transform final_top{}, smooth{};
  ex.State(top, &final_top);
  if (final_top.position.x < 0.4f || std::fabs(final_top.position.y - 0.1f) > 0.03f) Fail("the released box is not on the ground");
  if (!client.SamplePose(top, edgephys_now_s(), EDGEPHYS_INTERP_DQ_SCLERP, &smooth)) Fail("sample_pose");
  std::printf("interpolated top box at %.3f %.3f %.3f\n", smooth.position.x, smooth.position.y, smooth.position.z);
  for (uint32_t id : boxes) {
    edgephys_transform t{};
    ex.State(id, &t);
    PrintPose(id, t);
  }
  std::fflush(stdout);
  // An ownership handoff of a local-physics object: a baton this client simulates itself (not
  // offloaded) goes to another player; once the relay announces it, the new owner's states are
  // the ones everyone gets.
  edgephys_spawn_desc_init(&d);
  d.transform.position = {2, 0.1f, 0};
  d.rigid_body = &dynamic;
  d.colliders = &box;
  d.collider_count = 1;
  const uint32_t baton = ex.Spawn(d);
  ex.RunFor(0.2);
  const uint32_t other = ex.other_player;
  if (other == 0) Fail("nobody to hand the baton to");
  Check(client.HandOver(baton, other), "hand over");
  ex.WaitFor([&] { return client.Owner(baton) == other; }, 5, "the handoff was not announced");
  edgephys_transform held{};
  ex.WaitFor([&] { return ex.State(baton, &held) && std::fabs(held.position.y - 0.5f) < 0.01f; }, 5,
             "no state of the baton from its new owner");
  std::printf("handoff: entity %u to player %u, its state now comes from player %u\n", baton, other, other);
  std::fflush(stdout);
  ex.RunFor(1.0);  // let a watcher see the same settled poses before we leave
  Check(client.Disconnect(), "disconnect");
  std::printf("ok\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4 || argc > 5 || (argc == 5 && std::string(argv[4]) != "--watch")) {
    std::fprintf(stderr, "usage: %s <relay host:port> <join token> <room> [--watch]\n", argv[0]);
    return 2;
  }
  if (edgephys_abi_version() != EDGEPHYS_ABI_VERSION) Fail("libedgephys ABI mismatch");
  std::printf("edgephys %s, ABI %u\n", edgephys_version_string(), edgephys_abi_version());
  edgephys_client_config cfg;
  edgephys_client_config_init(&cfg);
  const bool watch = argc == 5;
  cfg.queue_state_events = watch ? 1 : 0;
  Client client(&cfg);
  if (!client.ok()) Fail("create");
  return watch ? Watch(client, argv[1], argv[2], argv[3]) : Run(client, argv[1], argv[2], argv[3]);
}
