"""The same frame drawn by Mesa's llvmpipe through moderngl: the CPU OpenGL rasterizer to beat.

    python bench/llvmpipe.py                          # approach scene, 4x MSAA, 1280 x 1024
    python bench/llvmpipe.py --frames 10 --image f.npy --json r.json
    python bench/llvmpipe.py --scene quads            # the random quads, 640 x 480 (SCENES)
    python bench/llvmpipe.py --scene overdraw4t       # 10,000 quads, depth complexity 4, a quarter
                                                      # translucent, 1280 x 1024

bench_visibility.py runs this file in a child process (run_llvmpipe()), so that the Mesa
environment below is set before libEGL loads and a driver crash cannot take the bench down.

What is drawn: every face of every instance of the Database (channel_worker.pipeline.scene),
fan-triangulated, in world metres made relative to the eyepoint in float64 before narrowing to
float32; flat colours lit exactly as geometry.to_eye lights them (linear RGB, the face's opacity
as alpha). Per frame, with one vertex shader doing the channel's rotation and its off-axis
frustum (docs/conventions.md, the same tangents as project.screen_mapping):

1. clear to the sky colour; draw the earth as the part of the screen below the horizon line
   (horizon.earth_dz_screen), no depth;
2. opaque faces with the depth test and back-face culling, by layer: layer 0, then each layer of
   faces painted "on" another with a polygon offset of -layer (the GL way to draw a decal);
3. translucent faces sorted back to front by centroid distance (sorted on the CPU each frame),
   depth test on, depth writes off, blended "over";
4. resolve the 4x multi-sample framebuffer into a single-sample one (glBlitFramebuffer) and
   glFinish.

The multi-sample colour buffer is RGBA8 holding linear values (the cheapest format llvmpipe
offers; the PNG is sRGB-encoded on the way out). Depth is 24-bit with the near plane pushed out
to just short of the nearest polygon (see gl_near), so 5 cm wall decals do not fight at 2 km.

The Mesa environment (MESA_ENV) forces the software path: LIBGL_ALWAYS_SOFTWARE=1,
GALLIUM_DRIVER=llvmpipe, EGL_PLATFORM=surfaceless, and LP_NUM_THREADS (rasterizer threads; 0
rasterizes in the calling thread). The child is also pinned to one CPU (sched_setaffinity)
before the context exists, so every thread Mesa starts shares that core. GL_RENDERER is
recorded and must name llvmpipe, or the result says so and counts as unavailable.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from channel_worker.pipeline.contract import View
from channel_worker.pipeline.geometry.backface import eliminate_backfaces
from channel_worker.pipeline.geometry.clip import clip
from channel_worker.pipeline.geometry.cull import cull
from channel_worker.pipeline.geometry.transform import to_eye
from channel_worker.pipeline.geometry.view import (
    earth_dz_screen,
    make_view,
)
from channel_worker.pipeline.scene.database import Database
from services.rig.frame import ChannelSpec, Eyepoint

#: Environment that makes Mesa use llvmpipe on a surfaceless EGL display (no X, no GPU).
MESA_ENV = {"LIBGL_ALWAYS_SOFTWARE": "1", "GALLIUM_DRIVER": "llvmpipe",
            "EGL_PLATFORM": "surfaceless"}

_VERTEX_SHADER = """
#version 330
uniform mat3 world_to_eye;  // rows: eye x (right), y (up), z (forward) in world axes
uniform mat4 projection;    // off-axis frustum, eye z forward
in vec3 in_pos;             // world metres relative to the eyepoint
in vec4 in_rgba;            // linear RGB, opacity
out vec4 v_rgba;
void main() {
    vec3 eye = world_to_eye * in_pos;
    gl_Position = projection * vec4(eye, 1.0);
    v_rgba = in_rgba;
}
"""
_FRAGMENT_SHADER = """
#version 330
in vec4 v_rgba;
out vec4 f_rgba;
void main() { f_rgba = v_rgba; }
"""
_EARTH_VERTEX_SHADER = """
#version 330
in vec2 in_ndc;
void main() { gl_Position = vec4(in_ndc, 0.0, 1.0); }
"""
_EARTH_FRAGMENT_SHADER = """
#version 330
uniform vec3 colour;
out vec4 f_rgba;
void main() { f_rgba = vec4(colour, 1.0); }
"""


# ---------------------------------------------------------------------------------------------
# Geometry from the Database (no GL needed: testable and reusable).

def world_faces(database: Database, eye: np.ndarray) -> dict[str, np.ndarray]:
    """Every face of every instance, fan-triangulated, relative to the eye.

    Returns:
        "tri_pos": (T, 3, 3) float64 triangle corners, world axes, metres from the eye;
        "tri_face": (T,) int64 face of each triangle; per face "rgba" (F, 4) float32 linear
        lit colour and opacity, "layer" (F,) int16, "centroid" (F, 3) float64 metres from the
        eye; "face_count".
    """
    tris, tri_face, rgba, layers, centroids = [], [], [], [], []
    face = 0
    for i in range(database.instance_model.shape[0]):
        model = database.models[int(database.instance_model[i])]
        rot = database.instance_rotation[i]
        verts = (model.vertices @ rot.T) + (database.instance_position[i] - eye)  # float64
        world_n = model.normal @ rot.T
        lambert = np.clip(world_n @ database.sun, 0.0, 1.0)
        light = database.ambient + (1.0 - database.ambient) * lambert
        colour = model.colour * light[:, None].astype(np.float32)
        for k in range(model.face_count):
            idx = model.face_index[model.face_start[k]:model.face_start[k + 1]]
            pts = verts[idx]
            for j in range(1, len(idx) - 1):  # fan: (0, j, j + 1) keeps the winding
                tris.append(pts[[0, j, j + 1]])
                tri_face.append(face)
            rgba.append((*colour[k], model.opacity[k]))
            layers.append(model.layer[k])
            centroids.append(pts.mean(axis=0))
            face += 1
    return {"tri_pos": np.array(tris, np.float64), "tri_face": np.array(tri_face, np.int64),
            "rgba": np.array(rgba, np.float32), "layer": np.array(layers, np.int16),
            "centroid": np.array(centroids, np.float64), "face_count": np.int64(face)}


def gl_near(database: Database, view: View) -> float:
    """Near plane for the GL depth buffer, metres: 90 % of the depth of the nearest visible
    point, capped to [view.near, 50].

    The nearest visible point is found with the pipeline's own stages (cull, to_eye, backface
    elimination, frustum clipping): a clipped convex polygon's smallest depth is at a vertex.
    A far-out near plane spends the 24 bits of depth where the scene is, and clips nothing.
    """
    polys = clip(eliminate_backfaces(to_eye(database, cull(database, view), view)), view)
    nearest = float(polys.verts[:, 2].min()) if polys.polygon_count else view.far
    return float(np.clip(0.9 * nearest, view.near, 50.0))


def projection_matrix(view: View, near: float) -> np.ndarray:
    """(4, 4) float32 GL clip matrix for eye coordinates with z forward (w = z).

    x_ndc = (2 x/z - (r + l)) / (r - l) with l, r the frustum's tangents (project.screen_mapping
    maps the same tangents to pixels 0..width), likewise y, and depth near -> -1, far -> +1.
    """
    lf, r, b, t = view.tan_left, view.tan_right, view.tan_bottom, view.tan_top
    f, n = view.far, near
    m = np.array([
        [2.0 / (r - lf), 0.0, -(r + lf) / (r - lf), 0.0],
        [0.0, 2.0 / (t - b), -(t + b) / (t - b), 0.0],
        [0.0, 0.0, (f + n) / (f - n), -2.0 * f * n / (f - n)],
        [0.0, 0.0, 1.0, 0.0],
    ])
    return m.astype(np.float32)


def earth_polygon_ndc(database: Database, view: View) -> np.ndarray:
    """(N, 2) float32 NDC corners of the screen region below the horizon (the earth); N may be 0.

    The world z of the ray through screen point (sx, sy) is kx sx + ky sy + k0 (pixels, y down);
    the earth is where it is negative (an eye above the earth plane). The screen rectangle is
    clipped against that half-plane.
    """
    kx, ky, k0 = earth_dz_screen(view)
    w, h = view.width, view.height
    corners = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
    out = []
    for i, p in enumerate(corners):
        q = corners[(i + 1) % 4]
        dp, dq = kx * p[0] + ky * p[1] + k0, kx * q[0] + ky * q[1] + k0
        if dp < 0.0:
            out.append(p)
        if (dp < 0.0) != (dq < 0.0):
            s = dp / (dp - dq)
            out.append((p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])))
    pts = np.array(out, np.float64).reshape(-1, 2)
    ndc = np.column_stack([2.0 * pts[:, 0] / w - 1.0, 1.0 - 2.0 * pts[:, 1] / h])
    return ndc.astype(np.float32)


# ---------------------------------------------------------------------------------------------
# The GL side.

def render_llvmpipe(database: Database, channel: ChannelSpec, eyepoint: Eyepoint, *,
                    frames: int = 20, warmup: int = 3, samples: int = 4,
                    image_path: Path | None = None) -> dict[str, Any]:
    """Draw the frame `warmup + frames` times with moderngl on a standalone EGL context.

    Call in a process whose environment holds MESA_ENV (and LP_NUM_THREADS) before moderngl is
    imported; run_llvmpipe() does that. Returns the record (see bench/README.md); with
    image_path, saves the last resolved frame there as (H, W, 3) float32 linear RGB, row 0 at
    the top (.npy).
    """
    import moderngl

    view = make_view(channel, eyepoint)
    faces = world_faces(database, view.eye)
    near = gl_near(database, view)
    ctx = moderngl.create_context(standalone=True, backend="egl")
    info = {k: str(v) for k, v in ctx.info.items()
            if k in ("GL_RENDERER", "GL_VENDOR", "GL_VERSION")}
    record: dict[str, Any] = {"available": True, "gl": info, "gl_near_m": near,
                              "samples": samples, "width": channel.width,
                              "height": channel.height, "frames": frames, "warmup": warmup,
                              "lp_num_threads": os.environ.get("LP_NUM_THREADS"),
                              "cpu_affinity": sorted(os.sched_getaffinity(0))
                              if hasattr(os, "sched_getaffinity") else None}
    if "llvmpipe" not in info.get("GL_RENDERER", ""):
        record.update(available=False,
                      reason=f"GL_RENDERER is {info.get('GL_RENDERER')!r}, not llvmpipe")
        return record

    size = (channel.width, channel.height)
    msaa = ctx.framebuffer(color_attachments=[ctx.renderbuffer(size, 4, samples=samples)],
                           depth_attachment=ctx.depth_renderbuffer(size, samples=samples))
    resolved = ctx.framebuffer(color_attachments=[ctx.renderbuffer(size, 4)])
    prog = ctx.program(vertex_shader=_VERTEX_SHADER, fragment_shader=_FRAGMENT_SHADER)
    prog["world_to_eye"].write(view.world_to_eye.astype(np.float32).T.tobytes())  # column-major
    prog["projection"].write(projection_matrix(view, near).T.tobytes())
    earth_prog = ctx.program(vertex_shader=_EARTH_VERTEX_SHADER,
                             fragment_shader=_EARTH_FRAGMENT_SHADER)
    earth_prog["colour"].value = tuple(float(c) for c in database.earth_colour)

    # Vertex data: (pos xyz, rgba) float32 per triangle corner; opaque grouped by layer.
    rgba = faces["rgba"]
    tri_face = faces["tri_face"]
    opaque_tri = rgba[tri_face, 3] >= 1.0
    corner = np.concatenate([faces["tri_pos"].astype(np.float32),
                             np.repeat(rgba[tri_face][:, None, :], 3, axis=1)], axis=2)
    layer_of_tri = faces["layer"][tri_face]
    draws = []  # (vao, layer) for the opaque faces, layer by layer
    for layer in np.unique(layer_of_tri[opaque_tri]):
        sel = opaque_tri & (layer_of_tri == layer)
        vbo = ctx.buffer(np.ascontiguousarray(corner[sel]).tobytes())
        draws.append((ctx.vertex_array(prog, [(vbo, "3f 4f", "in_pos", "in_rgba")]), int(layer)))
    trans_tri = np.flatnonzero(~opaque_tri)
    # GL refuses an empty buffer: a scene without translucent faces gets one unused corner.
    trans_vbo = ctx.buffer(np.ascontiguousarray(corner[trans_tri]).tobytes() if trans_tri.size
                           else corner[:1].tobytes())
    trans_face = tri_face[trans_tri]
    trans_ibo = ctx.buffer(reserve=max(4, 12 * trans_tri.size))
    trans_vao = ctx.vertex_array(prog, [(trans_vbo, "3f 4f", "in_pos", "in_rgba")],
                                 index_buffer=trans_ibo, index_element_size=4)
    earth_vbo = ctx.buffer(reserve=8 * 8)
    earth_vao = ctx.vertex_array(earth_prog, [(earth_vbo, "2f", "in_ndc")])
    sky = tuple(float(c) for c in database.sky_colour)
    centroid = faces["centroid"]

    def frame() -> None:
        # CPU work a GL image generator does each frame: sort the translucent faces, place the
        # horizon. (Static here, but redone every frame as a moving eyepoint needs it.)
        dist = np.einsum("ij,ij->i", centroid, centroid)
        order = np.argsort(-dist[trans_face], kind="stable")  # farthest triangle first
        trans_ibo.write((order[:, None] * 3 + np.arange(3)).astype(np.uint32).tobytes())
        earth = earth_polygon_ndc(database, view)
        msaa.use()
        ctx.clear(*sky, 1.0, depth=1.0)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND | moderngl.CULL_FACE)
        if earth.shape[0] >= 3:
            earth_vbo.write(earth.tobytes())
            earth_vao.render(moderngl.TRIANGLE_FAN, vertices=earth.shape[0])
        ctx.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.front_face = "ccw"
        ctx.depth_func = "<="
        for vao, layer in draws:
            ctx.polygon_offset = (-float(layer), -float(layer))
            vao.render(moderngl.TRIANGLES)
        ctx.polygon_offset = (0.0, 0.0)
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        ctx.depth_mask = False
        if trans_tri.size:
            trans_vao.render(moderngl.TRIANGLES, vertices=3 * trans_tri.size)
        ctx.depth_mask = True
        ctx.copy_framebuffer(resolved, msaa)  # multi-sample resolve
        ctx.finish()

    for _ in range(warmup):
        frame()
    times = []
    for _ in range(frames):
        t0 = time.perf_counter()
        frame()
        times.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    pixels = resolved.read(components=3, dtype="f1")
    readback_s = time.perf_counter() - t0
    median = statistics.median(times)
    record.update(
        triangles=int(tri_face.size), faces=int(faces["face_count"]),
        translucent_triangles=int(trans_tri.size),
        frame_ms=[1e3 * t for t in times], median_ms=1e3 * median, fps=1.0 / median,
        readback_ms=1e3 * readback_s,
        statistic="median over frames of: sort + draw + MSAA resolve + glFinish (readback apart)")
    if image_path is not None:
        img = np.frombuffer(pixels, np.uint8).reshape(channel.height, channel.width, 3)
        np.save(image_path, (img[::-1].astype(np.float32) / 255.0))  # GL rows run bottom-up
    ctx.release()
    return record


def run_llvmpipe(*, threads: int = 1, frames: int = 20, warmup: int = 3, samples: int = 4,
                 cpu: int | None = None, image_path: Path | None = None,
                 timeout_s: float = 900.0, scene: str = "approach") -> dict[str, Any]:
    """Run this file in a child process with MESA_ENV and LP_NUM_THREADS=threads, pinned to
    `cpu` (default: the lowest CPU this process may use), on a scene of SCENES with its
    eyepoint and channel (default the approach).

    Never raises for a missing or failing llvmpipe: the record then has available = False and
    the reason (moderngl not installed, no EGL, the child's error output, ...).
    """
    env = {**os.environ, **MESA_ENV, "LP_NUM_THREADS": str(threads)}
    if cpu is None and hasattr(os, "sched_getaffinity"):
        cpu = min(os.sched_getaffinity(0))
    with _temp_json() as out:
        cmd = [sys.executable, str(Path(__file__).resolve()), "--frames", str(frames),
               "--warmup", str(warmup), "--samples", str(samples), "--json", str(out),
               "--scene", scene]
        if cpu is not None:
            cmd += ["--cpu", str(cpu)]
        if image_path is not None:
            cmd += ["--image", str(image_path)]
        try:
            proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout_s,
                                  check=False)
        except subprocess.TimeoutExpired:
            return {"available": False, "reason": f"llvmpipe run timed out after {timeout_s:g} s"}
        if proc.returncode != 0 or not out.exists():
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-5:]
            return {"available": False,
                    "reason": f"llvmpipe child exited {proc.returncode}: " + " | ".join(tail)}
        return json.loads(out.read_text(encoding="utf-8"))


def _approach() -> tuple[Database, ChannelSpec, Eyepoint]:
    from bench.scenes.approach import approach_channel, approach_eyepoint, approach_scene
    from channel_worker.pipeline.scene.load import parse_scene

    return (parse_scene(approach_scene(), source="bench approach scene"), approach_channel(),
            approach_eyepoint())


def _quads() -> tuple[Database, ChannelSpec, Eyepoint]:
    from channel_worker.pipeline.scene.load import parse_scene
    from channel_worker.testing.quads import QUADS_EYEPOINT, QUADS_FOV_DEG, quads_scene_doc

    return (parse_scene(quads_scene_doc(), source="quads"),
            ChannelSpec.symmetric("quads", 640, 480, QUADS_FOV_DEG), Eyepoint.of(*QUADS_EYEPOINT))


def _overdraw(depth_complexity: float,
              translucent: float) -> Callable[[], tuple[Database, ChannelSpec, Eyepoint]]:
    def build() -> tuple[Database, ChannelSpec, Eyepoint]:
        from channel_worker.pipeline.scene.load import parse_scene
        from channel_worker.testing.quads import (
            OVERDRAW_FOV_DEG,
            OVERDRAW_SIZE,
            QUADS_EYEPOINT,
            overdraw_scene_doc,
        )

        return (parse_scene(overdraw_scene_doc(depth_complexity, translucent=translucent),
                            source="overdraw"),
                ChannelSpec.symmetric("overdraw", *OVERDRAW_SIZE, OVERDRAW_FOV_DEG),
                Eyepoint.of(*QUADS_EYEPOINT))

    return build


#: The overdraw scenes (bench_visibility.py's "overdraw" section): name -> (depth complexity,
#: translucent fraction) of channel_worker/testing/quads.py's overdraw_scene_doc, whose other
#: arguments keep their defaults (10,000 quads, seed 2028).
OVERDRAW_SCENES: dict[str, tuple[float, float]] = {
    "overdraw4": (4.0, 0.0),
    "overdraw8": (8.0, 0.0),
    "overdraw4t": (4.0, 0.25),
    "overdraw8t": (8.0, 0.25),
}

#: The scenes the child can draw: name -> (database, channel, eyepoint). approach: the
#: bench's main case (bench/scenes/approach.py); quads: the 200 random eye-facing quads of
#: channel_worker/testing/quads.py at 640 x 480, whose exact coverage is known; the overdraw
#: scenes at 1280 x 1024.
SCENES: dict[str, Callable[[], tuple[Database, ChannelSpec, Eyepoint]]] = {
    "approach": _approach,
    "quads": _quads,
    **{name: _overdraw(*params) for name, params in OVERDRAW_SCENES.items()},
}


class _temp_json:
    """A temporary JSON file path, removed afterwards."""

    def __enter__(self) -> Path:
        import tempfile

        fd, name = tempfile.mkstemp(suffix=".json")
        os.close(fd)
        self.path = Path(name)
        self.path.unlink()
        return self.path

    def __exit__(self, *exc: object) -> None:
        self.path.unlink(missing_ok=True)


def main(argv: list[str] | None = None) -> int:
    """Child-process entry: set up Mesa, draw, write the record; returns the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--cpu", type=int, default=None, help="pin to this CPU first")
    parser.add_argument("--threads", type=int, default=None,
                        help="LP_NUM_THREADS (default: the environment's, else 1)")
    parser.add_argument("--json", type=Path, default=None, help="write the record here")
    parser.add_argument("--image", type=Path, default=None, help="save the frame (.npy)")
    parser.add_argument("--scene", choices=list(SCENES), default="approach",
                        help="what to draw (default: the approach)")
    args = parser.parse_args(argv)
    for key, value in MESA_ENV.items():
        os.environ.setdefault(key, value)
    if args.threads is not None:
        os.environ["LP_NUM_THREADS"] = str(args.threads)
    os.environ.setdefault("LP_NUM_THREADS", "1")
    if args.cpu is not None:
        os.sched_setaffinity(0, {args.cpu})  # before Mesa starts its threads: they inherit it

    try:
        import moderngl  # noqa: F401
    except ImportError as exc:
        record: dict[str, Any] = {"available": False,
                                  "reason": f"moderngl is not installed ({exc}); "
                                            "pip install -e '.[bench]'"}
    else:
        database, channel, eyepoint = SCENES[args.scene]()
        try:
            record = render_llvmpipe(database, channel, eyepoint, frames=args.frames,
                                     warmup=args.warmup, samples=args.samples,
                                     image_path=args.image)
        except Exception as exc:
            record = {"available": False, "reason": f"{type(exc).__name__}: {exc}"}
    record["scene"] = args.scene
    record["env"] = {k: os.environ.get(k) for k in (*MESA_ENV, "LP_NUM_THREADS")}
    text = json.dumps(record, indent=1)
    if args.json is not None:
        args.json.write_text(text + "\n", encoding="utf-8")
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
