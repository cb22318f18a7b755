/* The edgephys SDK example, in C (the same program exists in C++, C# and Python):
 * join a room, say hello to the others with a chat line (an application message), agree with
 * the others on a shared "current step" (a room property, compare-and-set), spawn a
 * local-physics head and two hands, offload a stack of three boxes to
 * PhyS, wait until they fall and settle, grab the top one with the right hand, carry it aside,
 * release it, and print every physics event. Prints the settled poses of the boxes, then hands
 * a local-physics baton to another player and waits until that player's state of it arrives.
 *
 *   stack_and_grab <relay host:port> <join token> <room>
 *
 * Output lines: "agreed step: <v> (written by player <id>)", "event <name> <a> <b>",
 * "handoff: entity <id> to player <id>, ...", "pose <id> <x> <y> <z> <qx> <qy> <qz> <qw>", and a
 * final "ok" (exit 0) or "FAIL: <why>" (exit 1). Checked by tests/sdk_examples_test.sh. */
#include <edgephys/edgephys.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define BOXES 3
#define MAX_EVENTS 256

static edgephys_client* client;
static uint32_t box_ids[BOXES], ground_id, head_id, hand_ids[2];
static edgephys_event events[MAX_EVENTS];
static int event_count;
static int connected, joined;
static uint32_t other_player; /* the latest other player who joined */

static const char* EventName(uint32_t type) {
  switch (type) {
    case EDGEPHYS_EVENT_COLLISION_ENTER: return "collision_enter";
    case EDGEPHYS_EVENT_COLLISION_EXIT: return "collision_exit";
    case EDGEPHYS_EVENT_TRIGGER_ENTER: return "trigger_enter";
    case EDGEPHYS_EVENT_TRIGGER_EXIT: return "trigger_exit";
    case EDGEPHYS_EVENT_GRABBED: return "grabbed";
    case EDGEPHYS_EVENT_RELEASED: return "released";
    case EDGEPHYS_EVENT_GUARD_RESET: return "guard_reset";
    default: return NULL;
  }
}

static void Fail(const char* why) {
  printf("FAIL: %s (%s)\n", why, edgephys_last_error());
  exit(1);
}

static void Check(edgephys_status st, const char* what) {
  if (st != EDGEPHYS_OK) {
    printf("FAIL: %s: %s: %s\n", what, edgephys_status_name(st), edgephys_last_error());
    exit(1);
  }
}

static void Sleep10ms(void) {
  struct timespec ts = {0, 10 * 1000 * 1000};
  nanosleep(&ts, NULL);
}

/* One frame: update, then drain the event queue. */
static void Pump(void) {
  Check(edgephys_client_update(client, edgephys_now_s()), "update");
  edgephys_event ev;
  for (;;) {
    Check(edgephys_client_poll_event(client, &ev), "poll");
    if (ev.type == EDGEPHYS_EVENT_NONE) break;
    if (ev.type == EDGEPHYS_EVENT_CONNECTED) connected = 1;
    if (ev.type == EDGEPHYS_EVENT_JOINED) joined = 1;
    if (ev.type == EDGEPHYS_EVENT_PLAYER_JOINED) other_player = ev.player_id;
    if (ev.type == EDGEPHYS_EVENT_REJECTED) Fail("rejected by the relay");
    if (ev.type == EDGEPHYS_EVENT_DISCONNECTED) Fail("disconnected");
    if (ev.type == EDGEPHYS_EVENT_ERROR) printf("error reason %u entity %u: %s\n", ev.code, ev.entity_id, ev.detail);
    const char* name = EventName(ev.type);
    if (name != NULL) {
      printf("event %s %u %u\n", name, ev.entity_id, ev.other_id);
      if (event_count < MAX_EVENTS) events[event_count++] = ev;
    }
  }
  Sleep10ms();
}

/* Runs frames for `seconds`. */
static void RunFor(double seconds) {
  const double end = edgephys_now_s() + seconds;
  while (edgephys_now_s() < end) Pump();
}

static int BoxState(int i, edgephys_transform* out) {
  edgephys_entity e;
  if (edgephys_client_get_entity(client, box_ids[i], &e) != EDGEPHYS_OK || !e.has_state) return 0;
  *out = e.transform;
  return 1;
}

/* True once every box has a state and none moved more than 1 mm in 0.5 s. */
static int Settled(void) {
  edgephys_transform before[BOXES], after[BOXES];
  for (int i = 0; i < BOXES; ++i) if (!BoxState(i, &before[i])) return 0;
  RunFor(0.5);
  for (int i = 0; i < BOXES; ++i) {
    if (!BoxState(i, &after[i])) return 0;
    float dx = after[i].position.x - before[i].position.x, dy = after[i].position.y - before[i].position.y,
          dz = after[i].position.z - before[i].position.z;
    if (sqrtf(dx * dx + dy * dy + dz * dz) > 0.001f) return 0;
  }
  return 1;
}

static void WaitSettled(double timeout_s) {
  const double end = edgephys_now_s() + timeout_s;
  while (!Settled()) {
    if (edgephys_now_s() > end) Fail("the boxes did not settle");
    Pump();
  }
}

static int HasEvent(uint32_t type, uint32_t a, uint32_t b) {
  for (int i = 0; i < event_count; ++i) {
    if (events[i].type == type && events[i].entity_id == a && events[i].other_id == b) return i;
  }
  return -1;
}

static uint32_t Spawn(edgephys_spawn_desc* d) {
  uint32_t id = 0;
  Check(edgephys_client_spawn(client, d, &id), "spawn");
  return id;
}

static void Publish(uint32_t id, float x, float y, float z) {
  edgephys_transform t = {{x, y, z}, {0, 0, 0, 1}};
  Check(edgephys_client_publish_transform(client, id, &t), "publish");
}

int main(int argc, char** argv) {
  if (argc != 4) {
    fprintf(stderr, "usage: %s <relay host:port> <join token> <room>\n", argv[0]);
    return 2;
  }
  if (edgephys_abi_version() != EDGEPHYS_ABI_VERSION) Fail("libedgephys ABI mismatch");
  printf("edgephys %s, ABI %u\n", edgephys_version_string(), edgephys_abi_version());

  edgephys_client_config cfg;
  Check(edgephys_client_config_init(&cfg), "config");
  Check(edgephys_client_create(&cfg, &client), "create");
  Check(edgephys_client_connect(client, argv[1], argv[2], edgephys_now_s()), "connect");
  for (double end = edgephys_now_s() + 5; !connected; Pump()) if (edgephys_now_s() > end) Fail("no connection");
  Check(edgephys_client_join(client, argv[3]), "join");
  for (double end = edgephys_now_s() + 5; !joined; Pump()) if (edgephys_now_s() > end) Fail("no join");
  /* A chat line to everyone else in the room (reliable; they get it with our player id). */
  static const char chat[] = "hello from the C example";
  Check(edgephys_client_send_message(client, EDGEPHYS_TO_OTHERS, 0, chat, sizeof chat - 1), "chat");

  /* A shared "current step" (a room property anyone may write), proposed with compare-and-set,
   * expected version 0 (only if nobody set it yet). Another player may propose at the same
   * time: the relay takes exactly one proposal, the other writer gets PROPERTY_CONFLICT with
   * the winner's value, and both end on the same step. */
  edgephys_property_value proposal;
  memset(&proposal, 0, sizeof proposal);
  proposal.type = EDGEPHYS_PROPERTY_INT64;
  proposal.int_value = 1;
  Check(edgephys_client_compare_and_set_property(client, 0, "step", &proposal, 0, EDGEPHYS_AUTHORITY_ANYONE, NULL),
        "step");
  edgephys_property step;
  memset(&step, 0, sizeof step);
  step.struct_size = sizeof step;
  for (double end = edgephys_now_s() + 5;
       edgephys_client_get_property(client, 0, "step", &step, NULL, 0) != EDGEPHYS_OK || step.version < 1; Pump()) {
    if (edgephys_now_s() > end) Fail("no agreed step");
  }
  printf("agreed step: %lld (written by player %u)\n", (long long)step.value.int_value, step.writer);

  /* The scene, dissected: a static ground handed to PhyS... */
  edgephys_collider ground_box;
  edgephys_collider_init(&ground_box);
  ground_box.half_extents = (edgephys_vec3){5, 0.5f, 5};
  edgephys_spawn_desc d;
  edgephys_spawn_desc_init(&d);
  d.transform.position.y = -0.5f;
  d.flags = EDGEPHYS_FLAG_OFFLOADED;
  d.name = "ground";
  d.colliders = &ground_box;
  d.collider_count = 1;
  ground_id = Spawn(&d);

  /* ...a local-physics head and hands: kinematic bodies mirrored into PhyS... */
  edgephys_rigid_body kinematic;
  edgephys_rigid_body_init(&kinematic);
  kinematic.kinematic = 1;
  kinematic.mass = 0;
  edgephys_collider head_sphere, trigger;
  edgephys_collider_init(&head_sphere);
  head_sphere.shape = EDGEPHYS_SHAPE_SPHERE;
  head_sphere.radius = 0.1f;
  trigger = head_sphere;
  trigger.radius = 0.15f;
  trigger.is_trigger = 1;
  edgephys_spawn_desc_init(&d);
  d.transform.position = (edgephys_vec3){0, 1.6f, 1};
  d.flags = EDGEPHYS_FLAG_AVATAR;
  d.name = "head";
  d.rigid_body = &kinematic;
  d.colliders = &head_sphere;
  d.collider_count = 1;
  head_id = Spawn(&d);
  for (int h = 0; h < 2; ++h) {
    edgephys_spawn_desc_init(&d);
    d.transform.position = (edgephys_vec3){h == 0 ? -0.3f : 0.3f, 1.2f, 1};
    d.flags = EDGEPHYS_FLAG_HAND;
    d.name = h == 0 ? "left hand" : "right hand";
    d.rigid_body = &kinematic;
    d.colliders = &trigger;
    d.collider_count = 1;
    hand_ids[h] = Spawn(&d);
  }

  /* ...and a stack of dynamic boxes, offloaded: PhyS simulates and owns them. */
  edgephys_rigid_body dynamic;
  edgephys_rigid_body_init(&dynamic);
  edgephys_collider box;
  edgephys_collider_init(&box);
  box.half_extents = (edgephys_vec3){0.1f, 0.1f, 0.1f};
  for (int i = 0; i < BOXES; ++i) {
    edgephys_spawn_desc_init(&d);
    d.transform.position = (edgephys_vec3){0, 0.3f + 0.3f * (float)i, 0};
    d.flags = EDGEPHYS_FLAG_OFFLOADED | EDGEPHYS_FLAG_INTERACTABLE | EDGEPHYS_FLAG_REPORT_CONTACTS;
    d.name = "box";
    d.rigid_body = &dynamic;
    d.colliders = &box;
    d.collider_count = 1;
    box_ids[i] = Spawn(&d);
  }
  printf("spawned ground %u head %u hands %u %u boxes %u %u %u\n", ground_id, head_id, hand_ids[0],
         hand_ids[1], box_ids[0], box_ids[1], box_ids[2]);

  /* They fall and settle into a stack (box centres at 0.1, 0.3, 0.5 m). */
  WaitSettled(10);
  for (int i = 0; i < BOXES; ++i) {
    edgephys_transform t = {{0, 0, 0}, {0, 0, 0, 1}};
    BoxState(i, &t);
    printf("settled box %u at %.3f %.3f %.3f\n", box_ids[i], t.position.x, t.position.y, t.position.z);
    if (fabsf(t.position.y - (0.1f + 0.2f * (float)i)) > 0.03f) Fail("a box is not where the stack puts it");
  }

  /* The right hand hovers the top box (its trigger reports it), grabs it, carries it aside. */
  const uint32_t top = box_ids[BOXES - 1], hand = hand_ids[1];
  edgephys_transform top_t = {{0, 0, 0}, {0, 0, 0, 1}};
  BoxState(BOXES - 1, &top_t);
  Publish(hand, top_t.position.x, top_t.position.y + 0.05f, top_t.position.z);
  for (double end = edgephys_now_s() + 3; HasEvent(EDGEPHYS_EVENT_TRIGGER_ENTER, hand, top) < 0; Pump()) {
    if (edgephys_now_s() > end) Fail("the hand's trigger never reported the box");
  }
  Check(edgephys_client_grab(client, top, hand), "grab");
  for (double end = edgephys_now_s() + 3; HasEvent(EDGEPHYS_EVENT_GRABBED, top, hand) < 0; Pump()) {
    if (edgephys_now_s() > end) Fail("no Grabbed event");
  }
  const double start = edgephys_now_s();
  for (double t = 0; t < 1.0; t = edgephys_now_s() - start) {
    Publish(hand, 0.6f * (float)t, top_t.position.y + 0.05f + 0.4f * (float)t, top_t.position.z);
    Pump();
  }
  Check(edgephys_client_release(client, top), "release");
  Publish(hand, 0.3f, 1.2f, 1);
  for (double end = edgephys_now_s() + 3; HasEvent(EDGEPHYS_EVENT_RELEASED, top, hand) < 0; Pump()) {
    if (edgephys_now_s() > end) Fail("no Released event");
  }
  WaitSettled(10);

  /* Order: Grabbed, then the box leaves the one below (collision exit), then Released, then it
   * lands on the ground (collision enter). */
  const int grabbed = HasEvent(EDGEPHYS_EVENT_GRABBED, top, hand);
  const uint32_t below = box_ids[BOXES - 2];
  const int left_stack = HasEvent(EDGEPHYS_EVENT_COLLISION_EXIT, below < top ? below : top, below < top ? top : below);
  const int released = HasEvent(EDGEPHYS_EVENT_RELEASED, top, hand);
  int landed = -1;
  for (int i = released + 1; i < event_count; ++i) {
    if (events[i].type == EDGEPHYS_EVENT_COLLISION_ENTER && (events[i].entity_id == top || events[i].other_id == top)) {
      landed = i;
      break;
    }
  }
  if (!(grabbed >= 0 && left_stack > grabbed && released > left_stack && landed > released)) {
    printf("FAIL: event order grabbed %d left_stack %d released %d landed %d\n", grabbed, left_stack, released, landed);
    return 1;
  }
  edgephys_transform final_top = {{0, 0, 0}, {0, 0, 0, 1}};
  BoxState(BOXES - 1, &final_top);
  if (final_top.position.x < 0.4f || fabsf(final_top.position.y - 0.1f) > 0.03f) Fail("the released box is not on the ground beside the stack");

  /* Render-side: the interpolated pose of the top box is close to its latest state. */
  edgephys_transform smooth = {{0, 0, 0}, {0, 0, 0, 1}};
  Check(edgephys_client_sample_pose(client, top, edgephys_now_s(), EDGEPHYS_INTERP_DQ_SCLERP, &smooth), "sample_pose");
  printf("interpolated top box at %.3f %.3f %.3f\n", smooth.position.x, smooth.position.y, smooth.position.z);

  for (int i = 0; i < BOXES; ++i) {
    edgephys_transform t = {{0, 0, 0}, {0, 0, 0, 1}};
    BoxState(i, &t);
    printf("pose %u %.6f %.6f %.6f %.6f %.6f %.6f %.6f\n", box_ids[i], t.position.x, t.position.y,
           t.position.z, t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w);
  }
  fflush(stdout);

  /* An ownership handoff of a local-physics object: a baton this client simulates itself (not
   * offloaded) goes to another player; once the relay announces it, the new owner's states are
   * the ones everyone gets. */
  edgephys_spawn_desc_init(&d);
  d.transform.position = (edgephys_vec3){2, 0.1f, 0};
  d.name = "baton";
  d.rigid_body = &dynamic;
  d.colliders = &box;
  d.collider_count = 1;
  const uint32_t baton = Spawn(&d);
  RunFor(0.2);
  if (other_player == 0) Fail("nobody to hand the baton to");
  Check(edgephys_client_hand_over(client, baton, other_player), "hand over");
  uint32_t owner = 0;
  for (double end = edgephys_now_s() + 5; edgephys_client_get_owner(client, baton, &owner) != EDGEPHYS_OK || owner != other_player; Pump()) {
    if (edgephys_now_s() > end) Fail("the handoff was not announced");
  }
  for (double end = edgephys_now_s() + 5;; Pump()) {
    edgephys_entity e;
    if (edgephys_client_get_entity(client, baton, &e) == EDGEPHYS_OK && e.has_state &&
        fabsf(e.transform.position.y - 0.5f) < 0.01f) break;
    if (edgephys_now_s() > end) Fail("no state of the baton from its new owner");
  }
  printf("handoff: entity %u to player %u, its state now comes from player %u\n", baton, other_player, other_player);
  fflush(stdout);
  RunFor(1.0); /* let a watcher in the room see the same settled poses before we leave */
  Check(edgephys_client_disconnect(client), "disconnect");
  Check(edgephys_client_destroy(client), "destroy");
  printf("ok\n");
  return 0;
}
