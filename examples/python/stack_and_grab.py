#!/usr/bin/env python3
"""The edgephys SDK example in Python (bindings/python): the same program as
examples/c/stack_and_grab.c. Join, spawn a local-physics head and two hands, offload a stack of
three boxes, wait until they fall and settle, grab the top box, carry it aside, release it,
print every physics event, and end with the settled poses of the boxes.

    PYTHONPATH=bindings/python python3 examples/python/stack_and_grab.py <relay> <token> <room>
"""
import math
import sys
import time

import edgephys as ep


def main(relay, token, room):
    print(f"edgephys {ep.version()}, ABI {ep.lib.edgephys_abi_version()}")
    c = ep.Client()
    log = []  # physics events, in order
    state = {"connected": False, "joined": False, "other": 0}

    def pump():
        c.update()
        for ev in c.events():
            if ev.type == ep.EVENT_CONNECTED:
                state["connected"] = True
            elif ev.type == ep.EVENT_JOINED:
                state["joined"] = True
            elif ev.type == ep.EVENT_PLAYER_JOINED:
                state["other"] = ev.player_id  # the latest other player who joined
            elif ev.type in (ep.EVENT_REJECTED, ep.EVENT_DISCONNECTED):
                fail(f"connection ended (event {ev.type}, code {ev.code})")
            elif ev.type == ep.EVENT_ERROR:
                print(f"error reason {ev.code} entity {ev.entity_id}: {ev.detail.decode()}")
            if ev.type in ep.EVENT_NAMES:
                print(f"event {ep.EVENT_NAMES[ev.type]} {ev.entity_id} {ev.other_id}")
                log.append((ev.type, ev.entity_id, ev.other_id))
        time.sleep(0.01)

    def wait_for(done, timeout, what):
        end = ep.now_s() + timeout
        while not done():
            if ep.now_s() > end:
                fail(what)
            pump()

    def run_for(seconds):
        end = ep.now_s() + seconds
        while ep.now_s() < end:
            pump()

    def pos(entity_id):
        e = c.entity(entity_id)
        return None if e is None or not e.has_state else e.transform

    def settled(ids):
        before = [pos(i) for i in ids]
        if None in before:
            return False
        before = [(t.position.x, t.position.y, t.position.z) for t in before]
        run_for(0.5)
        after = [pos(i) for i in ids]
        if None in after:
            return False
        return all(math.dist(b, (a.position.x, a.position.y, a.position.z)) <= 0.001 for b, a in zip(before, after))

    def wait_settled(ids):
        end = ep.now_s() + 10
        while not settled(ids):
            if ep.now_s() > end:
                fail("the boxes did not settle")
            pump()

    def find(kind, a, b):
        return next((i for i, e in enumerate(log) if e == (kind, a, b)), -1)

    c.connect(relay, token)
    wait_for(lambda: state["connected"], 5, "no connection")
    c.join(room)
    wait_for(lambda: state["joined"], 5, "no join")
    # A chat line to everyone else in the room (reliable; they get it with our player id).
    c.send_message(b"hello from the Python example", ep.TO_OTHERS)
    # A shared "current step" (a room property anyone may write), proposed with compare-and-set,
    # expected version 0 (only if nobody set it yet). Another player may propose at the same
    # time: the relay takes exactly one proposal, the other writer gets EVENT_PROPERTY_CONFLICT
    # with the winner's value, and both end on the same step.
    c.compare_and_set_property("step", 1, 0, authority=ep.AUTHORITY_ANYONE)
    wait_for(lambda: (c.get_property("step") or 0) and c.get_property("step").version >= 1, 5, "no agreed step")
    step = c.get_property("step")
    print(f"agreed step: {step.value} (written by player {step.writer})")

    ground = c.spawn(position=(0, -0.5, 0), flags=ep.FLAG_OFFLOADED, name="ground",
                     colliders=[ep.collider(ep.SHAPE_BOX, half_extents=(5, 0.5, 5))])
    kinematic = ep.rigid_body(kinematic=1, mass=0.0)
    head = c.spawn(position=(0, 1.6, 1), flags=ep.FLAG_AVATAR, name="head", rigid_body=kinematic,
                   colliders=[ep.collider(ep.SHAPE_SPHERE, radius=0.1)])
    hands = [c.spawn(position=(x, 1.2, 1), flags=ep.FLAG_HAND, name=name, rigid_body=kinematic,
                     colliders=[ep.collider(ep.SHAPE_SPHERE, radius=0.15, is_trigger=1)])
             for x, name in ((-0.3, "left hand"), (0.3, "right hand"))]
    boxes = [c.spawn(position=(0, 0.3 + 0.3 * i, 0), name="box",
                     flags=ep.FLAG_OFFLOADED | ep.FLAG_INTERACTABLE | ep.FLAG_REPORT_CONTACTS,
                     rigid_body=ep.rigid_body(), colliders=[ep.collider(ep.SHAPE_BOX, half_extents=(0.1, 0.1, 0.1))])
             for i in range(3)]
    print(f"spawned ground {ground} head {head} hands {hands[0]} {hands[1]} boxes {boxes[0]} {boxes[1]} {boxes[2]}")

    wait_settled(boxes)
    for i, b in enumerate(boxes):
        t = pos(b)
        print(f"settled box {b} at {t.position.x:.3f} {t.position.y:.3f} {t.position.z:.3f}")
        if abs(t.position.y - (0.1 + 0.2 * i)) > 0.03:
            fail("a box is not where the stack puts it")

    top, below, hand = boxes[2], boxes[1], hands[1]
    t0 = pos(top)
    y0 = t0.position.y + 0.05
    c.publish(hand, (t0.position.x, y0, t0.position.z))
    wait_for(lambda: find(ep.EVENT_TRIGGER_ENTER, hand, top) >= 0, 3, "the hand's trigger never reported the box")
    c.grab(top, hand)
    wait_for(lambda: find(ep.EVENT_GRABBED, top, hand) >= 0, 3, "no Grabbed event")
    start = ep.now_s()
    while (t := ep.now_s() - start) < 1.0:
        c.publish(hand, (0.6 * t, y0 + 0.4 * t, t0.position.z))
        pump()
    c.release(top)
    c.publish(hand, (0.3, 1.2, 1))
    wait_for(lambda: find(ep.EVENT_RELEASED, top, hand) >= 0, 3, "no Released event")
    wait_settled(boxes)

    grabbed = find(ep.EVENT_GRABBED, top, hand)
    left_stack = find(ep.EVENT_COLLISION_EXIT, below, top)
    released = find(ep.EVENT_RELEASED, top, hand)
    landed = next((i for i, (k, a, b) in enumerate(log)
                   if i > released and k == ep.EVENT_COLLISION_ENTER and top in (a, b)), -1)
    if not (0 <= grabbed < left_stack < released < landed):
        fail(f"event order grabbed {grabbed} left_stack {left_stack} released {released} landed {landed}")
    final = pos(top)
    if final.position.x < 0.4 or abs(final.position.y - 0.1) > 0.03:
        fail("the released box is not on the ground")
    smooth = c.sample_pose(top)
    print(f"interpolated top box at {smooth.position.x:.3f} {smooth.position.y:.3f} {smooth.position.z:.3f}")
    for b in boxes:
        t = pos(b)
        p, q = t.position, t.rotation
        print(f"pose {b} {p.x:.6f} {p.y:.6f} {p.z:.6f} {q.x:.6f} {q.y:.6f} {q.z:.6f} {q.w:.6f}", flush=True)
    # An ownership handoff of a local-physics object: a baton this client simulates itself (not
    # offloaded) goes to another player; once the relay announces it, the new owner's states
    # are the ones everyone gets.
    baton = c.spawn(position=(2, 0.1, 0), name="baton", rigid_body=ep.rigid_body(),
                    colliders=[ep.collider(ep.SHAPE_BOX, half_extents=(0.1, 0.1, 0.1))])
    run_for(0.2)
    other = state["other"]
    if other == 0:
        fail("nobody to hand the baton to")
    c.hand_over(baton, other)
    wait_for(lambda: c.owner(baton) == other, 5, "the handoff was not announced")
    wait_for(lambda: pos(baton) is not None and abs(pos(baton).position.y - 0.5) < 0.01, 5,
             "no state of the baton from its new owner")
    print(f"handoff: entity {baton} to player {other}, its state now comes from player {other}", flush=True)
    run_for(1.0)  # let a watcher see the same settled poses before we leave
    c.disconnect()
    c.close()
    print("ok")


def fail(why):
    print(f"FAIL: {why}", flush=True)
    sys.exit(1)


if __name__ == "__main__":
    if len(sys.argv) != 4:
        print(f"usage: {sys.argv[0]} <relay host:port> <join token> <room>", file=sys.stderr)
        sys.exit(2)
    main(*sys.argv[1:])
