# Compares the "pose <id> x y z qx qy qz qw" lines of two logs: every pose of the second file
# (the example's) must be in the first (the watcher's) within 1 mm and 0.1 degree. Prints one
# line per entity; exits 1 on a missing entity, a difference beyond the bounds, or fewer than
# 3 poses. Used by sdk_examples_test.sh; tested by compare_poses_test.sh.
#   awk -f compare_poses.awk WATCHER_LOG EXAMPLE_LOG
#
# The angle between the two rotations is 2 acos(|a.b| / (|a| |b|)). The quaternions are
# printed with 6 decimals, so their norms are 1 only to ~1e-6, and without the division a
# rotation compared with its own printed copy could read up to ~0.2 degree (e.g.
# 0.000503 -0.003018 0.000503 0.999995 has |q|^2 = 1 - 3.86e-7: 0.1006 degree against itself).
function norm(x, y, z, w) { return sqrt(x * x + y * y + z * z + w * w) }
FNR == NR { if ($1 == "pose") w[$2] = $0; next }
$1 == "pose" {
  n++
  if (!($2 in w)) { print "FAIL: the watcher never saw entity " $2; bad = 1; next }
  split(w[$2], o, " ")
  dx = $3 - o[3]; dy = $4 - o[4]; dz = $5 - o[5]
  d = sqrt(dx * dx + dy * dy + dz * dz)
  na = norm($6, $7, $8, $9); nb = norm(o[6], o[7], o[8], o[9])
  if (na < 0.5 || nb < 0.5) { print "FAIL: entity " $2 " has no unit rotation"; bad = 1; next }
  dot = ($6 * o[6] + $7 * o[7] + $8 * o[8] + $9 * o[9]) / (na * nb)
  if (dot < 0) dot = -dot; if (dot > 1) dot = 1
  deg = 2 * atan2(sqrt(1 - dot * dot), dot) * 180 / 3.14159265358979
  printf "entity %s: example vs watcher %.4f mm, %.4f deg\n", $2, d * 1000, deg
  if (d > 0.001 || deg > 0.1) { print "FAIL: entity " $2 " differs beyond the codec bounds"; bad = 1 }
}
END { if (n < 3) { print "FAIL: fewer than 3 poses printed"; bad = 1 } exit bad }
