"""Unit test of the Python binding: bad arguments raise EdgephysError with the C status, never
crash the interpreter; reasons reach the game named and explained. Run:
EDGEPHYS_LIBRARY=.../libedgephys.so python3 -m unittest test_edgephys; the relay tests need a
relay (tests/with_relay.sh sets EDGEPHYS_RELAY and tokens for players 1-4) and are skipped without."""
import contextlib
import ctypes
import math
import os
import time
import unittest

import edgephys as ep


class _RoomPair:
    """Two clients joining one room. pump() updates both, joins each on CONNECTED, notes JOINED
    and hands every other event to on_event(client, event), then sleeps 5 ms."""

    def __init__(self, test, a, b, room, on_event):
        self.test, self.clients, self.room, self.on_event = test, (a, b), room, on_event
        self.joined = set()

    def pump(self):
        for c in self.clients:
            c.update()
            for ev in c.events():
                if ev.type == ep.EVENT_CONNECTED:
                    c.join(self.room)
                elif ev.type == ep.EVENT_JOINED:
                    self.joined.add(c)
                else:
                    self.on_event(c, ev)
        time.sleep(0.005)

    def join_both(self, deadline):
        """Pumps until both joined (failing the test at `deadline`); returns pump."""
        while len(self.joined) < 2 and time.monotonic() < deadline:
            self.pump()
        self.test.assertEqual(len(self.joined), 2, "both clients joined")
        return self.pump


@contextlib.contextmanager
def _connecting_pair(player):
    """Two clients on 127.0.0.1 connecting to the relay of tests/with_relay.sh with the tokens of
    `player` and `player` + 1 (EDGEPHYS_TOKEN_<n>); yields (a, b) and closes both after."""
    relay = os.environ["EDGEPHYS_RELAY"]
    with ep.Client(bind_address="127.0.0.1:0") as a, ep.Client(bind_address="127.0.0.1:0") as b:
        a.connect(relay, os.environ["EDGEPHYS_TOKEN_%d" % player])
        b.connect(relay, os.environ["EDGEPHYS_TOKEN_%d" % (player + 1)])
        yield a, b


class BindingTest(unittest.TestCase):
    def test_version(self):
        self.assertEqual(ep.lib.edgephys_abi_version(), ep.ABI_VERSION)
        self.assertTrue(ep.version())
        self.assertLessEqual(ep.now_s(), ep.now_s())

    def test_bad_arguments_raise(self):
        with ep.Client(bind_address="127.0.0.1:0") as c:
            with self.assertRaises(ep.EdgephysError) as e:
                c.connect("not an address", "AAAA")
            self.assertEqual(e.exception.status, ep.E_MALFORMED)
            with self.assertRaises(ep.EdgephysError) as e:
                c.join("lobby")
            self.assertEqual(e.exception.status, ep.E_NOT_CONNECTED)
            with self.assertRaises(ep.EdgephysError) as e:
                c.publish(65537, (math.nan, 0, 0))
            self.assertEqual(e.exception.status, ep.E_INVALID_ARGUMENT)
            with self.assertRaises(ep.EdgephysError) as e:
                c.spawn(position=(0, math.inf, 0))
            self.assertEqual(e.exception.status, ep.E_INVALID_ARGUMENT)
            with self.assertRaises(ep.EdgephysError) as e:
                c.spawn(colliders=[ep.collider(ep.SHAPE_BOX, half_extents=(math.nan, 1, 1))])
            self.assertEqual(e.exception.status, ep.E_INVALID_ARGUMENT)
            with self.assertRaises(ep.EdgephysError) as e:
                c.spawn_static([])  # scenery needs a collider
            self.assertEqual(e.exception.status, ep.E_INVALID_ARGUMENT)
            with self.assertRaises(ep.EdgephysError) as e:
                c.spawn_static([ep.collider(ep.SHAPE_BOX, half_extents=(5, 0.5, 5))], name="ground")
            self.assertEqual(e.exception.status, ep.E_NOT_CONNECTED)
            self.assertIsNone(c.entity(1))
            self.assertEqual(list(c.events()), [])
            self.assertEqual(c.info().state, 0)
            self.assertEqual(c.info().state_payloads_refused, 0)  # the struct's size matches the library's
            self.assertIsNone(c.state_format())  # not joined
            with self.assertRaises(ep.EdgephysError) as e:
                c.sample_pose(1, ep.INTERP_AUTO)
            self.assertEqual(e.exception.status, ep.E_NOT_FOUND)
            with self.assertRaises(ep.EdgephysError) as e:
                c.sample_pose(1, ep.INTERP_AUTO + 1)
            self.assertEqual(e.exception.status, ep.E_INVALID_ARGUMENT)
            for bad in (-0.1, 4.5, math.nan, math.inf):
                with self.assertRaises(ep.EdgephysError) as e:
                    c.set_max_playout_delay(bad)
                self.assertEqual(e.exception.status, ep.E_INVALID_ARGUMENT)
            c.set_max_playout_delay(0.1)
            c.set_max_playout_delay(0)
            self.assertIsNone(c.playout_delay(1))  # nothing of entity 1 has arrived
            with self.assertRaises(ep.EdgephysError) as e:
                c.connection_status()  # no connection yet
            self.assertEqual(e.exception.status, ep.E_NOT_CONNECTED)
            self.assertEqual(ctypes.sizeof(ep.ConnectionStatus), 144)  # the C struct's size
        with self.assertRaises(ep.EdgephysError) as e:
            ep.Client(bind_address="garbage")
        self.assertEqual(e.exception.status, ep.E_MALFORMED)


    def test_reason_names(self):
        self.assertEqual(ep.reason_name(ep.EVENT_REJECTED, ep.REJECT_BAD_TOKEN), "BadToken")
        self.assertEqual(ep.reason_name(ep.EVENT_REJECTED, 4), "RoomFull")
        self.assertEqual(ep.reason_name(ep.EVENT_DISCONNECTED, 4), "Kicked")
        self.assertEqual(ep.reason_name(ep.EVENT_DISCONNECTED, ep.DISCONNECT_RELIABLE_OVERFLOW),
                         "ReliableOverflow")
        self.assertEqual(ep.reason_name(ep.EVENT_ERROR, ep.REJECT_AUTH_REQUIRED), "AuthRequired")
        self.assertEqual(ep.reason_name(ep.EVENT_ERROR, ep.REJECT_BAD_PROOF + 1), "unknown")
        self.assertEqual(ep.reason_name(ep.EVENT_JOINED, 1), "unknown")
        ev = ep.Event()
        ev.type, ev.code = ep.EVENT_DISCONNECTED, ep.DISCONNECT_TIMEOUT
        self.assertEqual(ep.reason_name(ev), "Timeout")

    @unittest.skipUnless(os.environ.get("EDGEPHYS_RELAY"), "needs a relay (tests/with_relay.sh)")
    def test_a_tampered_token_is_rejected_with_reason_and_detail(self):
        token = os.environ["EDGEPHYS_TOKEN_1"]
        mid = len(token) // 2
        bad = token[:mid] + ("B" if token[mid] == "A" else "A") + token[mid + 1:]
        with ep.Client(bind_address="127.0.0.1:0") as c:
            c.connect(os.environ["EDGEPHYS_RELAY"], bad)
            rejected = None
            deadline = time.monotonic() + 5
            while rejected is None and time.monotonic() < deadline:
                c.update()
                rejected = next((e for e in c.events() if e.type == ep.EVENT_REJECTED), None)
                time.sleep(0.005)
            self.assertIsNotNone(rejected, "no REJECTED within 5 s")
            self.assertEqual(rejected.code, ep.REJECT_BAD_TOKEN)
            self.assertEqual(ep.reason_name(rejected), "BadToken")
            self.assertIn("token", ep.detail(rejected))
            self.assertEqual(c.info().reject_reason, ep.REJECT_BAD_TOKEN)


    @unittest.skipUnless(os.environ.get("EDGEPHYS_RELAY"), "needs a relay (tests/with_relay.sh)")
    def test_messages_reach_the_addressed_players_with_the_senders_id(self):
        room = os.environ["EDGEPHYS_ROOM"]
        with _connecting_pair(3) as (a, b):
            got = {a: [], b: []}
            unreliable = {a: [], b: []}
            deadline = time.monotonic() + 10

            def on_event(c, ev):
                if ev.type == ep.EVENT_MESSAGE and ev.flags & ep.MESSAGE_UNRELIABLE:
                    unreliable[c].append((ev.player_id, ev.payload))
                elif ev.type == ep.EVENT_MESSAGE:
                    got[c].append((ev.player_id, ev.payload))

            pump = _RoomPair(self, a, b, room, on_event).join_both(deadline)
            settle = time.monotonic() + 0.3  # both acknowledge their Joined (unreliable sends)
            while time.monotonic() < settle:
                pump()
            a.send_message_unreliable(b"ray", ep.TO_OTHERS)
            with self.assertRaises(ep.EdgephysError) as e:
                a.send_message_unreliable(bytes(ep.MAX_UNRELIABLE_MESSAGE_BYTES + 1))
            self.assertEqual(e.exception.status, ep.E_TOO_LARGE)
            big = bytes(range(256)) * 200  # 51,200 bytes: fragmented
            a.send_message(b"hello, room", ep.TO_ROOM)
            a.send_message(big, ep.TO_OTHERS)
            b.send_message(b"just for 3", ep.TO_PLAYER, to_player=3)
            b.send_message(b"")
            with self.assertRaises(ep.EdgephysError) as e:
                a.send_message(bytes(ep.MAX_MESSAGE_BYTES + 1))
            self.assertEqual(e.exception.status, ep.E_TOO_LARGE)
            while (len(got[a]) < 3 or len(got[b]) < 3) and time.monotonic() < deadline:
                pump()
            # In order per sender; different senders' messages may interleave.
            by_sender = lambda msgs: sorted(msgs, key=lambda m: m[0])  # stable
            self.assertEqual(by_sender(got[a]), [(3, b"hello, room"), (4, b"just for 3"), (4, b"")])
            self.assertEqual(by_sender(got[b]), [(3, b"hello, room"), (3, big), (4, b"")])
            self.assertEqual(unreliable, {a: [], b: [(3, b"ray")]})  # loopback: nothing lost

    def test_property_values_are_checked_before_sending(self):
        with ep.Client(bind_address="127.0.0.1:0") as c:
            with self.assertRaises(ep.EdgephysError) as e:
                c.set_property("step", 1)
            self.assertEqual(e.exception.status, ep.E_NOT_CONNECTED)
            with self.assertRaises(TypeError):
                c.set_property("step", object())
            self.assertIsNone(c.get_property("step"))

    @unittest.skipUnless(os.environ.get("EDGEPHYS_RELAY"), "needs a relay (tests/with_relay.sh)")
    def test_properties_converge_and_one_compare_and_set_wins(self):
        room = os.environ["EDGEPHYS_ROOM"]
        with _connecting_pair(5) as (a, b):
            changed = {a: [], b: []}
            conflicts = {a: [], b: []}
            errors = {a: [], b: []}
            deadline = time.monotonic() + 10

            def on_event(c, ev):
                if ev.type == ep.EVENT_PROPERTY_CHANGED:
                    changed[c].append(ev.property)
                elif ev.type == ep.EVENT_PROPERTY_CONFLICT:
                    conflicts[c].append((ev.other_id, ev.property))
                elif ev.type == ep.EVENT_ERROR:
                    errors[c].append((ev.code, ep.detail(ev)))

            pump = _RoomPair(self, a, b, room, on_event).join_both(deadline)
            values = {"py.flag": True, "py.count": -3, "py.gain": 0.5, "py.title": "step one",
                      "py.blob": b"\x00\xff", "py.where": (1.0, 2.0, 3.0), "py.turn": (0.0, 0.0, 0.0, 1.0)}
            for k, v in values.items():
                a.set_property(k, v, authority=ep.AUTHORITY_ANYONE)
            with self.assertRaises(ep.EdgephysError) as e:
                a.set_property("py.bad", math.nan)
            self.assertEqual(e.exception.status, ep.E_INVALID_ARGUMENT)
            while (b.get_property("py.turn") is None) and time.monotonic() < deadline:
                pump()
            for k, v in values.items():
                p = b.get_property(k)
                self.assertIsNotNone(p, k)
                self.assertEqual(p.value, v, k)
                self.assertEqual((p.version, p.writer), (1, 5), k)
            # Both advance "py.count" from version 1: one wins, the other sees its value.
            ra = a.compare_and_set_property("py.count", 10, 1)
            rb = b.compare_and_set_property("py.count", 20, 1)
            while not (conflicts[a] or conflicts[b]) and time.monotonic() < deadline:
                pump()
            for _ in range(20):
                pump()
            self.assertEqual(len(conflicts[a]) + len(conflicts[b]), 1)
            loser, request = (a, ra) if conflicts[a] else (b, rb)
            got_request, current = conflicts[loser][0]
            self.assertEqual(got_request, request)
            self.assertEqual(current.version, 2)
            self.assertEqual(current.value, 20 if loser is a else 10)
            self.assertEqual(a.get_property("py.count").value, current.value)
            self.assertEqual(b.get_property("py.count").value, current.value)
            # Owner-only: B may not write A's property.
            a.set_property("py.mine", 1)
            b.set_property("py.flag", False)  # anyone may
            while b.get_property("py.mine") is None and time.monotonic() < deadline:
                pump()
            b.set_property("py.mine", 2)
            while not errors[b] and time.monotonic() < deadline:
                pump()
            self.assertEqual(errors[b][0][0], ep.REJECT_NOT_OWNER)
            self.assertIn("py.mine", errors[b][0][1])
            self.assertEqual(a.get_property("py.flag").value, False)

    @unittest.skipUnless(os.environ.get("EDGEPHYS_RELAY"), "needs a relay (tests/with_relay.sh)")
    def test_ownership_hand_over_and_refused_request(self):
        room = os.environ["EDGEPHYS_ROOM"]
        with _connecting_pair(7) as (a, b):
            changes = {a: [], b: []}
            errors = {a: [], b: []}
            spawned = {a: set(), b: set()}
            deadline = time.monotonic() + 10

            def on_event(c, ev):
                if ev.type == ep.EVENT_SPAWNED:
                    spawned[c].add(ev.entity_id)
                elif ev.type == ep.EVENT_OWNERSHIP_CHANGED:
                    changes[c].append((ev.entity_id, ev.player_id, ev.code))
                elif ev.type == ep.EVENT_ERROR:
                    errors[c].append((ev.code, ev.entity_id))

            pump = _RoomPair(self, a, b, room, on_event).join_both(deadline)

            def hear(n):  # both clients heard n ownership changes (their messages race)
                while (len(changes[a]) < n or len(changes[b]) < n) and time.monotonic() < deadline:
                    pump()

            box = a.spawn(position=(0, 1, 0))
            while box not in spawned[b] and time.monotonic() < deadline:
                pump()
            self.assertEqual(b.owner(box), 7)
            # Refused while A forbids takeover (the default).
            b.request_ownership(box)
            while not errors[b] and time.monotonic() < deadline:
                pump()
            self.assertEqual(errors[b], [(ep.REJECT_TAKEOVER_REFUSED, box)])
            self.assertEqual(ep.reason_name(ep.EVENT_ERROR, ep.REJECT_TAKEOVER_REFUSED), "TakeoverRefused")
            # Handed over: both hear it; B publishes it now, A no longer may.
            a.hand_over(box, 8)
            hear(1)
            self.assertEqual(changes[a], [(box, 8, 1)])
            self.assertEqual(changes[b], [(box, 8, 1)])
            self.assertEqual((a.owner(box), b.owner(box)), (8, 8))
            b.publish(box, (0.5, 1, 0))
            with self.assertRaises(ep.EdgephysError) as e:
                a.publish(box, (0.5, 1, 0))
            self.assertEqual(e.exception.status, ep.E_NOT_FOUND)
            b.release_ownership(box)
            hear(2)
            self.assertEqual(changes[a][-1], (box, 0, 2))
            # A takes it back, moves it and reads its motion; bad values are refused; A offloads
            # it; B takes it and starts from A's pose.
            a.request_ownership(box)
            hear(3)
            self.assertEqual(a.owner(box), 7)
            a.publish(box, (0.25, 1, 0))
            pose, lin, ang = a.owned_motion(box)
            self.assertEqual((pose.position.x, lin.x, ang.y), (0.25, 0, 0))
            with self.assertRaises(ep.EdgephysError) as e:
                b.owned_motion(box)
            self.assertEqual(e.exception.status, ep.E_NOT_FOUND)
            with self.assertRaises(ep.EdgephysError) as e:
                a.set_owner_leave(box, 9)
            self.assertEqual(e.exception.status, ep.E_INVALID_ARGUMENT)
            a.set_owner_leave(box, ep.OWNER_LEAVE_STAY)
            with self.assertRaises(ep.EdgephysError) as e:
                a.offload(box, (float("nan"), 0, 0))
            self.assertEqual(e.exception.status, ep.E_INVALID_ARGUMENT)
            def b_sees_pose():  # A's pose reached the relay (and B)
                e = b.entity(box)
                return e is not None and e.has_state and abs(e.transform.position.x - 0.25) < 0.002
            while not b_sees_pose() and time.monotonic() < deadline:
                pump()
            a.offload(box, (1, 0, 0))
            hear(4)
            self.assertEqual((a.owner(box), b.owner(box)), (0, 0))
            b.request_ownership(box)
            hear(5)
            self.assertEqual(b.owner(box), 8)
            pose, lin, ang = b.owned_motion(box)
            self.assertEqual(pose.position.x, 0.25)
            # grab_at: a hand this client does not own, and a non-finite pose, are refused here.
            with self.assertRaises(ep.EdgephysError) as e:
                a.grab_at(box, box, (0, 1, 0))
            self.assertEqual(e.exception.status, ep.E_NOT_FOUND)
            with self.assertRaises(ep.EdgephysError) as e:
                b.grab_at(box, box, (float("nan"), 1, 0))
            self.assertEqual(e.exception.status, ep.E_INVALID_ARGUMENT)


if __name__ == "__main__":
    unittest.main()
