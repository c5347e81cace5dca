"""Small vector / quaternion helpers used inside kernels (pure ``@ti.func``).

Quaternions are ``vec4`` (w, x, y, z), unit length, rotating body coordinates into table (world)
coordinates: v_world = R(q) v_body.
"""

import taichi as ti

from dem import ti_runtime

ti_runtime.quick_front_end()  # before this module's kernels are decorated

vec3 = ti.math.vec3
vec4 = ti.math.vec4
mat3 = ti.math.mat3
ivec2 = ti.math.ivec2

TINY_ANGLE = 2.0**-27  # below this, sin x and cos x round to exactly x and 1 in double precision


@ti.func
def quat_mul(a, b):
    """Hamilton product a * b."""
    return vec4(
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    )


@ti.func
def quat_to_mat(q):
    """Rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return mat3(
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    )


@ti.func
def quat_angle_between(a, b):
    """Rotation angle (rad) taking orientation a to orientation b."""
    c = ti.abs(a.dot(b))
    c = ti.min(c, 1.0)
    return 2.0 * ti.acos(c)
