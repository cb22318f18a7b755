"""Unit test of the Python binding: bad arguments raise EdgephysError with the C status, never
crash the interpreter. Run: EDGEPHYS_LIBRARY=.../libedgephys.so python3 -m unittest test_edgephys"""
import ctypes
import math
import unittest

import edgephys as ep


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
            self.assertIsNone(c.entity(1))
            self.assertEqual(list(c.events()), [])
            self.assertEqual(c.info().state, 0)
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


if __name__ == "__main__":
    unittest.main()
