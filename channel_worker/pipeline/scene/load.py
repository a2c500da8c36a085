"""Scene database: load and validate a scene JSON file (docs/scene-format.md)."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from services.rig.colour import srgb_to_linear
from services.rig.frame import hpr_matrix

from .atmosphere import KOSCHMIEDER, MAX_FOG_PLANES, Clouds, Fog, Haze, cloud_layer
from .database import Database, FaceTable, Model, TerrainLand
from .forest import with_near_trees
from .surfaces import (
    DEFAULT_CREASE_DEG,
    CodeParser,
    FaceSurfaces,
    gouraud_basis,
    texture_axes,
    vertex_normals,
)
from .textures import TextureStore, build_store, bundled_texture_path, empty_store, load_image, procedural

FORMAT = "ig-scene/1"
_COLOUR = re.compile(r"^#[0-9a-fA-F]{6}$")


class SceneError(ValueError):
    """A scene file that cannot be used; the message names the file, the JSON path and value."""


def bundled_scene_path() -> Path:
    """The airfield scene shipped with the package."""
    return Path(__file__).resolve().parents[2] / "data" / "airfield.json"


def demo_scene_path() -> Path:
    """The demo's scene: the bundled airfield on the bundled terrain, with haze (its terrain
    is built from matplotlib's sample DEM on first use, terrain/bundled.py)."""
    return Path(__file__).resolve().parents[2] / "data" / "airfield_terrain.json"


#: Height over which haze thins by e when the scene does not say (metres): haze sits mostly
#: in the lowest kilometre or two of the atmosphere.
DEFAULT_HAZE_SCALE_HEIGHT_M = 1200.0

#: Terrain databases a scene may name without a path ("database": "bundled:NAME").
BUNDLED_TERRAIN = ("jacksboro",)
#: terrain.detail.near_tree_px's default: a forest voxel wider than this many pixels is drawn
#: as polygon trees (scene/forest.py).
DEFAULT_NEAR_TREE_PX = 48.0

# Limits of a scene (docs/scene-format.md "Limits"). They are checked on the decoded document's
# list lengths before anything is built from it, so an oversized scene is refused in
# milliseconds instead of after gigabytes of arrays, and never drawn wrong.

#: Bytes of a scene file. Loading holds about twenty times the text (Python objects, then the
#: arrays) and validates each face in Python: a 48 MB file of 650,000 quads peaked at 1.06 GB
#: and took 270 s on the shared 2-core machine, so 16 MiB keeps a load near 350 MB and a
#: minute or so. The bundled airfield is under 100 kB.
MAX_SCENE_BYTES = 16 * 1024 * 1024

#: Vertices of one face, as written. The rasterizer tests a sample against every edge of a
#: polygon (an AND of half-planes, exact only while the polygon stays convex), and projection
#: snaps vertices to 1/256 pixel. Snapped vertices closer than a few 1/256 pixel turn into
#: axis-aligned steps whose half-planes cut through the polygon: a 100000-gon 90 pixels wide
#: projects to 57000 edges one 1/256 pixel long, four of which exclude its centre, so it drew
#: as a sliver or not at all. Measured over regular n-gons of every on-screen radius from 0.5
#: to 512 pixels, a 64-gon's coverage is exact to the snapping (1/400 pixel); 256 vertices miss
#: by up to 1/30 pixel and 1024 by half a pixel. Database polygons have a few vertices.
MAX_FACE_VERTICES = 64

#: Vertices of one model (its "vertices" list) and faces of one model (its "faces" list): a
#: model is a building, a runway, a vehicle; bigger meshes are split into models.
MAX_MODEL_VERTICES = 65_536
MAX_MODEL_FACES = 65_536

#: Faces a scene may draw, counted once per instance (a smooth model's faces as the triangles
#: it is drawn as), and their vertices: every frame in view may carry all of them through the
#: geometry stages and edge setup (about 200 bytes a face vertex), and feature ids are int32.
MAX_SCENE_FACES = 1_000_000
MAX_SCENE_FACE_VERTICES = 4_000_000


def load_scene(path: str | Path) -> Database:
    """Read, validate and index a scene file.

    Raises:
        SceneError: unreadable file, invalid JSON, or any value that breaks the format.
    """
    path = Path(path)
    try:
        # At most one byte more than the limit is read, whatever the file claims to be (a
        # pipe, a file still growing): the size is known before the text is held.
        with path.open("rb") as file:
            data = file.read(MAX_SCENE_BYTES + 1)
    except OSError as exc:
        raise SceneError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    if len(data) > MAX_SCENE_BYTES:
        raise SceneError(f"{path}: more than {MAX_SCENE_BYTES} bytes, the most a scene file may have "
                         f"(docs/scene-format.md, Limits)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(f"{path}: byte {exc.start}: not UTF-8 text") from exc
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SceneError(f"{path}: line {exc.lineno} column {exc.colno}: invalid JSON: {exc.msg}") from exc
    except RecursionError:
        raise SceneError(f"{path}: invalid JSON: nested too deeply") from None
    except ValueError as exc:  # an integer of more than 4300 digits (sys.int_info)
        raise SceneError(f"{path}: invalid JSON: {exc}") from exc
    return parse_scene(doc, source=str(path), base_dir=path.parent)


def parse_scene(doc: Any, *, source: str = "<scene>", base_dir: str | Path | None = None) -> Database:
    """Validate an already-decoded scene document; see load_scene.

    Args:
        base_dir: directory relative terrain paths are taken from (default: the current one).
    """
    return _Parser(source, Path(base_dir) if base_dir is not None else Path.cwd()).database(doc)


class _Parser:
    def __init__(self, source: str, base_dir: Path) -> None:
        self.source = source
        self.base_dir = base_dir
        self.codes = CodeParser(self.fail, self.number, {})

    def fail(self, where: str, message: str) -> SceneError:
        # The document itself has the empty path: "x.json: : missing key" named no place.
        return SceneError(f"{self.source}: {where or '(top level)'}: {message}")

    def obj(self, value: Any, where: str, required: set[str], optional: set[str]) -> dict:
        if not isinstance(value, dict):
            raise self.fail(where, f"expected an object, got {_show(value)}")
        for key in required:
            if key not in value:
                raise self.fail(where, f"missing key {key!r}")
        for key in value:
            if key not in required | optional:
                raise self.fail(f"{where}.{key}" if where else key, "unknown key")
        return value

    def number(self, value: Any, where: str, lo: float = -math.inf, hi: float = math.inf) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(where, f"expected a number, got {_show(value)}")
        try:
            number = float(value)
        except OverflowError:  # a JSON integer beyond float64 (1e309 written out)
            raise self.fail(where, f"{_show(value)} is not finite") from None
        if not math.isfinite(number):
            raise self.fail(where, f"{value} is not finite")
        if not lo <= number <= hi:
            raise self.fail(where, f"{value} is outside [{lo}, {hi}]")
        return number

    def vec3(self, value: Any, where: str) -> np.ndarray:
        if not isinstance(value, list) or len(value) != 3:
            raise self.fail(where, f"expected [x, y, z], got {_show(value)}")
        return np.array([self.number(v, f"{where}[{i}]") for i, v in enumerate(value)])

    def colour(self, value: Any, where: str) -> np.ndarray:
        if not isinstance(value, str) or not _COLOUR.match(value):
            raise self.fail(where, f"expected a colour '#rrggbb', got {_show(value)}")
        srgb = np.array([int(value[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0
        return srgb_to_linear(srgb).astype(np.float32)

    def database(self, doc: Any) -> Database:
        doc = self.obj(doc, "", {"format", "sky", "earth", "models", "instances"},
                       {"name", "lighting", "terrain", "haze", "clouds", "fog", "textures",
                        "texture_codes"})
        if doc["format"] != FORMAT:
            raise self.fail("format", f"{_show(doc['format'])} is not {FORMAT!r}")
        self.check_limits(doc)
        sky = self.obj(doc["sky"], "sky", {"colour"}, set())
        earth = self.obj(doc["earth"], "earth", {"colour"}, {"height_m"})
        lighting = self.obj(doc.get("lighting", {}), "lighting", set(),
                            {"sun_heading_deg", "sun_elevation_deg", "ambient"})
        sun_h = math.radians(self.number(lighting.get("sun_heading_deg", 135.0), "lighting.sun_heading_deg"))
        sun_e = math.radians(self.number(lighting.get("sun_elevation_deg", 45.0),
                                         "lighting.sun_elevation_deg", -90.0, 90.0))
        sun = np.array([math.sin(sun_h) * math.cos(sun_e), math.cos(sun_h) * math.cos(sun_e), math.sin(sun_e)])
        ambient = self.number(lighting.get("ambient", 0.4), "lighting.ambient", 0.0, 1.0)

        models_doc = doc["models"]
        if not isinstance(models_doc, dict):
            raise self.fail("models", f"expected an object of models, got {_show(models_doc)}")
        store, texture_index = self.textures(doc.get("textures"))
        self.codes = CodeParser(self.fail, self.number, texture_index)
        self.codes.parse(doc.get("texture_codes"))
        models = [self.model(name, m) for name, m in models_doc.items()]
        index = {m.name: i for i, m in enumerate(models)}

        inst_doc = doc["instances"]
        if not isinstance(inst_doc, list):
            raise self.fail("instances", f"expected a list, got {_show(inst_doc)}")
        model_ix, positions, rotations, names = [], [], [], []
        for j, inst in enumerate(inst_doc):
            where = f"instances[{j}]"
            inst = self.obj(inst, where, {"model", "position"}, {"hpr", "name"})
            if not isinstance(inst["model"], str) or inst["model"] not in index:
                raise self.fail(f"{where}.model", f"{_show(inst['model'])} is not a model of this scene")
            hpr = self.vec3(inst.get("hpr", [0.0, 0.0, 0.0]), f"{where}.hpr")
            name = inst.get("name", f"{inst['model']}#{j}")
            if not isinstance(name, str):
                raise self.fail(f"{where}.name", f"expected a string, got {_show(name)}")
            model_ix.append(index[inst["model"]])
            positions.append(self.vec3(inst["position"], f"{where}.position"))
            rotations.append(hpr_matrix(*hpr))
            names.append(name)
        face_counts = np.array([models[m].face_count for m in model_ix], dtype=np.int64)
        face_base = (np.concatenate([[0], np.cumsum(face_counts)[:-1]]).astype(np.int64) if model_ix
                     else np.zeros(0, np.int64))
        database = Database(
            models=tuple(models),
            instance_model=np.array(model_ix, dtype=np.int64),
            instance_position=np.array(positions, dtype=np.float64).reshape(-1, 3),
            instance_rotation=np.array(rotations, dtype=np.float64).reshape(-1, 3, 3),
            instance_names=tuple(names),
            instance_face_base=face_base,
            sky_colour=self.colour(sky["colour"], "sky.colour"),
            earth_colour=self.colour(earth["colour"], "earth.colour"),
            earth_height=self.number(earth.get("height_m", 0.0), "earth.height_m"),
            sun=sun,
            ambient=ambient,
            faces=FaceTable.of(tuple(models)),
            source=self.source,
            **self.terrain(doc.get("terrain")),
            haze=self.haze(doc.get("haze")),
            clouds=self.clouds(doc.get("clouds")),
            fog=self.fog(doc.get("fog")),
            textures=store,
            looks=self.codes.table(),
        )
        land = database.terrain_land
        return with_near_trees(database, land.near_tree_px) if land is not None else database

    def check_limits(self, doc: dict) -> None:
        """Refuse a scene beyond the limits (MAX_FACE_VERTICES ...) from list lengths alone,
        before any array is built; anything malformed is left to the full parse to name."""
        models = doc["models"] if isinstance(doc["models"], dict) else {}
        drawn: dict[str, tuple[int, int]] = {}  # model -> (faces, face vertices) it draws
        for name, model in models.items():
            if not isinstance(model, dict):
                continue
            where = f"models.{name}"
            faces = model.get("faces")
            faces = faces if isinstance(faces, list) else []
            self.at_most(len(faces), MAX_MODEL_FACES, f"{where}.faces", "faces", "a model")
            smooth = model.get("smooth", False) is not False
            n_faces = n_verts = 0
            for k, face in enumerate(faces):
                idx = face.get("indices") if isinstance(face, dict) else None
                if not isinstance(idx, list):
                    continue
                self.at_most(len(idx), MAX_FACE_VERTICES, f"{where}.faces[{k}].indices", "vertices", "a face")
                # A smooth model draws each face as a fan of triangles (fan()).
                triangles = max(len(idx) - 2, 1) if smooth else 1
                n_faces += triangles
                n_verts += 3 * triangles if smooth else len(idx)
            vertices = model.get("vertices")
            if isinstance(vertices, list):
                self.at_most(len(vertices), MAX_MODEL_VERTICES, f"{where}.vertices", "vertices", "a model")
            drawn[name] = (n_faces, n_verts)
        instances = doc["instances"] if isinstance(doc["instances"], list) else []
        total_faces = total_verts = 0
        for j, inst in enumerate(instances):
            name = inst.get("model") if isinstance(inst, dict) else None
            if not isinstance(name, str) or name not in drawn:
                continue
            faces, verts = drawn[name]
            total_faces += faces
            total_verts += verts
            # The instance where a total first passes its limit is the one named.
            self.at_most(total_faces, MAX_SCENE_FACES, f"instances[{j}]", "faces", "a scene",
                         " drawn over the instances so far")
            self.at_most(total_verts, MAX_SCENE_FACE_VERTICES, f"instances[{j}]", "face vertices",
                         "a scene", " drawn over the instances so far")

    def at_most(self, count: int, limit: int, where: str, what: str, holder: str, context: str = "") -> None:
        """Refuse count over limit: "WHERE: 100000 vertices, more than the 64 a face may have"."""
        if count > limit:
            raise self.fail(where, f"{count} {what}{context}, more than the {limit} {holder} may have "
                                   f"(docs/scene-format.md, Limits)")

    def textures(self, doc: Any) -> tuple[TextureStore, dict[str, int]]:
        """The optional "textures" key: name -> an image file (relative to the scene), a
        bundled texture or a procedural one, all in one store (textures.build_store)."""
        if doc is None:
            return empty_store(), {}
        if not isinstance(doc, dict) or not doc:
            raise self.fail("textures", f"expected an object of named textures, got {_show(doc)}")
        images, names = [], []
        for name, spec in doc.items():
            where = f"textures.{name}"
            spec = self.obj(spec, where, set(), {"image", "bundled", "procedural", "size", "seed"})
            kinds = [k for k in ("image", "bundled", "procedural") if k in spec]
            if len(kinds) != 1:
                raise self.fail(where, "expected exactly one of \"image\", \"bundled\", \"procedural\"")
            kind = kinds[0]
            value = spec[kind]
            if not isinstance(value, str):
                raise self.fail(f"{where}.{kind}", f"expected a string, got {_show(value)}")
            try:
                if kind == "image":
                    images.append(load_image(self.base_dir / value))
                elif kind == "bundled":
                    images.append(load_image(bundled_texture_path(value)))
                else:
                    size = self.number(spec.get("size", 256), f"{where}.size", 8, 1024)
                    seed = self.number(spec.get("seed", 0), f"{where}.seed", 0, 2**31 - 1)
                    images.append(procedural(value, int(size), int(seed)))
            except (ValueError, OSError) as exc:
                raise self.fail(f"{where}.{kind}", str(exc)) from exc
            names.append(name)
        try:
            store = build_store(images, names)
        except ValueError as exc:
            raise self.fail("textures", str(exc)) from exc
        return store, {n: i for i, n in enumerate(names)}

    def clouds(self, doc: Any) -> Clouds | None:
        """The optional "clouds" key: a procedural cloud layer (clouds.cloud_layer)."""
        if doc is None:
            return None
        keys = {"extent_m", "cell_m", "base_m", "thickness_m", "cover", "extinction_per_m",
                "colour"}
        doc = self.obj(doc, "clouds", keys, {"seed"})
        ext = doc["extent_m"]
        if not isinstance(ext, list) or len(ext) != 4:
            raise self.fail("clouds.extent_m", f"expected [x0, y0, x1, y1], got {_show(ext)}")
        ext = [self.number(v, f"clouds.extent_m[{i}]") for i, v in enumerate(ext)]
        if not (ext[0] < ext[2] and ext[1] < ext[3]):
            raise self.fail("clouds.extent_m", f"{ext} is empty (need x0 < x1 and y0 < y1)")
        cell = self.number(doc["cell_m"], "clouds.cell_m", 1.0)
        if (ext[2] - ext[0]) / cell * (ext[3] - ext[1]) / cell > 4e6:
            raise self.fail("clouds.cell_m", f"{cell} makes more than 4 million cells over "
                            f"{ext}: the cloud database is meant to be coarse")
        seed = doc.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise self.fail("clouds.seed", f"expected a non-negative integer, got {_show(seed)}")
        return cloud_layer(extent_m=tuple(ext), cell_m=cell,
                           base_m=self.number(doc["base_m"], "clouds.base_m"),
                           thickness_m=self.number(doc["thickness_m"], "clouds.thickness_m", 0.0),
                           cover=self.number(doc["cover"], "clouds.cover", 0.0, 1.0),
                           extinction_per_m=self.number(doc["extinction_per_m"],
                                                        "clouds.extinction_per_m", 0.0),
                           colour=self.colour(doc["colour"], "clouds.colour"), seed=seed)

    def terrain(self, doc: Any) -> dict:
        """Database fields for the optional "terrain" key (the voxel database, loaded)."""
        if doc is None:
            return {}
        from channel_worker.pipeline.scene.terrain.database import TerrainError
        from channel_worker.pipeline.scene.terrain.store import load_terrain

        doc = self.obj(doc, "terrain", {"database"}, {"offset_m", "polygon_margin_m", "detail"})
        name = doc["database"]
        if not isinstance(name, str) or not name:
            raise self.fail("terrain.database", f"expected a path or 'bundled:NAME', got {_show(name)}")
        try:
            if name.startswith("bundled:"):
                if name[len("bundled:"):] not in BUNDLED_TERRAIN:
                    raise self.fail("terrain.database", f"{name!r} is not a bundled terrain; known: "
                                    + ", ".join(f"bundled:{n}" for n in BUNDLED_TERRAIN))
                from channel_worker.pipeline.scene.terrain.bundled import load_bundled_terrain
                db = load_bundled_terrain()
            else:
                db = load_terrain(self.base_dir / name)
        except TerrainError as exc:
            raise self.fail("terrain.database", str(exc)) from exc
        offset = self.vec3(doc.get("offset_m", [0.0, 0.0, 0.0]), "terrain.offset_m")
        margin = self.number(doc.get("polygon_margin_m", 1.0), "terrain.polygon_margin_m", 0.0, 100.0)
        db = dataclasses.replace(db, origin=np.asarray(db.origin, np.float64) + offset)
        land = self.terrain_detail(doc.get("detail"), db, offset)
        return {"terrain": db, "terrain_margin_m": margin, "terrain_land": land}

    def terrain_detail(self, doc: Any, db: Any, offset: np.ndarray) -> TerrainLand | None:
        """The optional "terrain.detail" key: texture codes per land class and the pads' grass."""
        if doc is None:
            return None
        doc = self.obj(doc, "terrain.detail", set(), {"grass", "field", "rock", "forest", "pad", "near_tree_px"})
        looks = {}
        for key in ("grass", "field", "rock", "forest"):
            code = doc.get(key)
            if code is not None and not isinstance(code, str):
                raise self.fail(f"terrain.detail.{key}", f"expected a texture code's name, got {_show(code)}")
            looks[key] = self.codes.look(code, False, f"terrain.detail.{key}")[0]
        pad_look, pad_colour, covered = -1, np.zeros(3, np.float32), False
        pads = np.zeros((0, 5))
        if "pad" in doc:
            pad = self.obj(doc["pad"], "terrain.detail.pad", {"colour"}, {"code", "areas", "covered"})
            code = pad.get("code")
            if code is not None and not isinstance(code, str):
                raise self.fail("terrain.detail.pad.code", f"expected a texture code's name, got {_show(code)}")
            pad_look = self.codes.look(code, False, "terrain.detail.pad.code")[0]
            pad_colour = self.colour(pad["colour"], "terrain.detail.pad.colour")
            covered = pad.get("covered", False)
            if not isinstance(covered, bool):
                raise self.fail("terrain.detail.pad.covered", f"expected true or false, got {_show(covered)}")
            if "areas" in pad:
                areas = pad["areas"]
                if not isinstance(areas, list) or not areas:
                    raise self.fail("terrain.detail.pad.areas", f"expected a list of [x0, y0, x1, y1, blend_m], "
                                                                f"got {_show(areas)}")
                rows = []
                for i, area in enumerate(areas):
                    where = f"terrain.detail.pad.areas[{i}]"
                    if not isinstance(area, list) or len(area) != 5:
                        raise self.fail(where, f"expected [x0, y0, x1, y1, blend_m], got {_show(area)}")
                    x0, y0, x1, y1, blend = (self.number(v, f"{where}[{k}]") for k, v in enumerate(area))
                    if not (x0 < x1 and y0 < y1 and blend >= 0.0):
                        raise self.fail(where, f"{area!r} is not x0 < x1, y0 < y1, blend_m >= 0"[:200])
                    rows.append([x0, y0, x1, y1, blend])
                pads = np.array(rows, np.float64)
            else:
                # The terrain database's flattened pads, moved with it.
                flatten = ((db.info or {}).get("recipe") or {}).get("flatten") or []
                pads = np.array([[p[0] + offset[0], p[1] + offset[1], p[2] + offset[0], p[3] + offset[1], p[5]]
                                 for p in flatten], np.float64).reshape(-1, 5)
        # The relief's mean brightness, from a sparse sample of the finest level's pages.
        sample = np.asarray(db.rgb[::max(1, db.rgb.shape[0] // 16), ::8, ::8, 0], np.uint8)
        linear = srgb_to_linear(sample.reshape(-1, 3) / 255.0)
        lum = float(np.mean(linear @ np.array([0.2126, 0.7152, 0.0722])))
        near_px = self.number(doc.get("near_tree_px", DEFAULT_NEAR_TREE_PX), "terrain.detail.near_tree_px", 0.0, 4096.0)
        return TerrainLand(grass=looks["grass"], field=looks["field"], rock=looks["rock"], forest=looks["forest"],
                           pad=pad_look, pad_covered=covered,
                           pad_colour=pad_colour, pads=pads, relief_luminance=max(lum, 1e-3),
                           near_tree_px=near_px)

    def haze(self, doc: Any) -> Haze | None:
        """The optional "haze" key."""
        if doc is None:
            return None
        doc = self.obj(doc, "haze", {"visibility_m", "colour"}, {"scale_height_m", "base_height_m"})
        vis = self.number(doc["visibility_m"], "haze.visibility_m", 1e-3)
        # null: no thinning with height (homogeneous haze).
        scale = doc.get("scale_height_m", DEFAULT_HAZE_SCALE_HEIGHT_M)
        scale = math.inf if scale is None else self.number(scale, "haze.scale_height_m", 1.0)
        return Haze(visibility_m=vis, scale_height_m=scale,
                    base_height_m=self.number(doc.get("base_height_m", 0.0), "haze.base_height_m"),
                    colour=self.colour(doc["colour"], "haze.colour"))

    def fog(self, doc: Any) -> Fog | None:
        """The optional "fog" key: US 5,535,374's strata, by extinction or by visibility per plane."""
        if doc is None:
            return None
        doc = self.obj(doc, "fog", {"colour"}, {"axis", "origin_m", "spacing_m", "extinction_per_m",
                                                "visibility_m", "table_spacing_m"})
        if ("extinction_per_m" in doc) == ("visibility_m" in doc):
            raise self.fail("fog", "give the strata as exactly one of \"extinction_per_m\" and "
                                   "\"visibility_m\" (a list, one value per sample plane)")
        key = "extinction_per_m" if "extinction_per_m" in doc else "visibility_m"
        values = doc[key]
        if not isinstance(values, list) or not 1 <= len(values) <= MAX_FOG_PLANES:
            raise self.fail(f"fog.{key}", f"expected a list of 1 to {MAX_FOG_PLANES} values, got "
                                          f"{_show(values)}")
        if key == "extinction_per_m":
            sigma = [self.number(v, f"fog.{key}[{i}]", 0.0) for i, v in enumerate(values)]
        else:
            # Meteorological visibility (Koschmieder, 2 % contrast): sigma = 3.912 / V; null is
            # clear air.
            sigma = [0.0 if v is None else KOSCHMIEDER / self.number(v, f"fog.{key}[{i}]", 1e-3)
                     for i, v in enumerate(values)]
        if len(values) > 1 and "spacing_m" not in doc:
            raise self.fail("fog.spacing_m", f"needed with {len(values)} sample planes")
        spacing = self.number(doc.get("spacing_m", 1.0), "fog.spacing_m", 1e-3)
        table = doc.get("table_spacing_m")
        if table is not None:
            table = self.number(table, "fog.table_spacing_m", 1e-3)
        axis = self.vec3(doc.get("axis", [0.0, 0.0, 1.0]), "fog.axis")
        if not float(np.linalg.norm(axis)) > 0.0:
            raise self.fail("fog.axis", f"{axis.tolist()} has no direction")
        return Fog(axis=axis, origin=self.vec3(doc.get("origin_m", [0.0, 0.0, 0.0]), "fog.origin_m"),
                   spacing_m=spacing, extinction=np.array(sigma), table_spacing_m=table,
                   colour=self.colour(doc["colour"], "fog.colour"))

    def model(self, name: str, doc: Any) -> Model:
        where = f"models.{name}"
        doc = self.obj(doc, where, {"vertices", "faces"}, {"smooth"})
        raw = doc["vertices"]
        if not isinstance(raw, list) or len(raw) < 3:
            raise self.fail(f"{where}.vertices", f"expected a list of at least 3 [x, y, z], got {_show(raw)}")
        vertices = np.array([self.vec3(v, f"{where}.vertices[{i}]") for i, v in enumerate(raw)])
        faces = doc["faces"]
        if not isinstance(faces, list) or not faces:
            raise self.fail(f"{where}.faces", f"expected a non-empty list, got {_show(faces)}")
        crease = self.smooth(doc.get("smooth", False), f"{where}.smooth")
        if crease is not None:
            faces = self.fan(faces, where)
        start: list[int] = [0]
        flat: list[int] = []
        colours: list[np.ndarray] = []
        opacity: list[float] = []
        normals: list[np.ndarray] = []
        layers: list[int] = []
        plane_vertex: list[int] = []
        for k, face in enumerate(faces):
            fwhere = f"{where}.faces[{k}]"
            face = self.obj(face, fwhere, {"indices", "colour"},
                            {"opacity", "on", "layer", "texture", "texture_plane"})
            idx = face["indices"]
            if not isinstance(idx, list) or len(idx) < 3:
                raise self.fail(f"{fwhere}.indices", f"expected at least 3 vertex indices, got {_show(idx)}")
            for i, v in enumerate(idx):
                if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v < len(vertices):
                    raise self.fail(f"{fwhere}.indices[{i}]",
                                    f"index {_show(v)} out of range (model has {len(vertices)} vertices)")
            if len(set(idx)) != len(idx):
                raise self.fail(f"{fwhere}.indices", f"{idx} repeats a vertex")
            normals.append(self.face_normal(vertices[idx], f"{fwhere}.indices"))
            flat.extend(idx)
            start.append(len(flat))
            colours.append(self.colour(face["colour"], f"{fwhere}.colour"))
            opacity.append(self.number(face.get("opacity", 1.0), f"{fwhere}.opacity", 0.0, 1.0))
            if opacity[-1] == 0.0:
                raise self.fail(f"{fwhere}.opacity", "0 makes the face invisible; remove it instead")
            layer, pv = self.face_layer(face, k, layers, plane_vertex, flat, start, vertices, normals, fwhere)
            layers.append(layer)
            plane_vertex.append(pv)
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        centre = (lo + hi) / 2.0
        radius = float(np.sqrt(((vertices - centre) ** 2).sum(axis=1)).max())
        surface = self.surfaces(faces, where, vertices, [flat[start[k]:start[k + 1]] for k in range(len(faces))],
                                np.array(normals), crease)
        return Model(name, vertices, np.array(start, np.int64), np.array(flat, np.int64),
                     np.array(colours, np.float32), np.array(opacity, np.float32),
                     np.array(normals), centre, radius, np.array(layers, np.int16),
                     np.array(plane_vertex, np.int64), surface)

    def smooth(self, value: Any, where: str) -> float | None:
        """A model's "smooth": false, true or {"crease_deg": angle}; the crease angle or None."""
        if value is False:
            return None
        if value is True:
            return DEFAULT_CREASE_DEG
        value = self.obj(value, where, set(), {"crease_deg"})
        return self.number(value.get("crease_deg", DEFAULT_CREASE_DEG), f"{where}.crease_deg", 0.0, 180.0)

    def fan(self, faces: list, where: str) -> list:
        """A smooth model's faces as triangles (fans from each face's first vertex): the
        light is linear over a triangle, so its interpolation is the same however the screen
        is turned (surfaces.py). Painted faces ("on") are refused: their layers follow face
        indices, which the fan renumbers."""
        out = []
        for k, face in enumerate(faces):
            if isinstance(face, dict) and "on" in face:
                raise self.fail(f"{where}.faces[{k}].on", "a smooth model cannot have painted faces")
            idx = face.get("indices") if isinstance(face, dict) else None
            if not isinstance(idx, list) or len(idx) <= 3:
                out.append(face)
                continue
            for i in range(1, len(idx) - 1):
                out.append({**face, "indices": [idx[0], idx[i], idx[i + 1]]})
        return out

    def surfaces(self, faces: list, where: str, vertices: np.ndarray, indices: list,
                 normals: np.ndarray, crease: float | None) -> FaceSurfaces:
        """Each face's look, texture map and (smooth models) Gouraud terms (surfaces.py)."""
        n = len(faces)
        look = np.full(n, -1, np.int32)
        tex_map = np.zeros((n, 2, 4))
        corner_normals = vertex_normals(vertices, indices, normals, crease) if crease is not None else None
        vnorm = np.zeros((n, 3, 3))
        basis = np.zeros((n, 3, 3))
        for k, face in enumerate(faces):
            fwhere = f"{where}.faces[{k}]"
            code = face.get("texture")
            if code is not None and not isinstance(code, str):
                raise self.fail(f"{fwhere}.texture", f"expected the name of a texture code, got {_show(code)}")
            if "texture_plane" in face and code is None:
                raise self.fail(f"{fwhere}.texture_plane", "a texture plane needs a \"texture\"")
            row, rotation = self.codes.look(code, crease is not None, f"{fwhere}.texture")
            look[k] = row
            if code is not None:
                plane = self.obj(face.get("texture_plane", {}), f"{fwhere}.texture_plane", set(),
                                 {"origin_m", "u_axis"})
                origin = self.vec3(plane.get("origin_m", [0.0, 0.0, 0.0]), f"{fwhere}.texture_plane.origin_m")
                hint = self.vec3(plane["u_axis"], f"{fwhere}.texture_plane.u_axis") if "u_axis" in plane else None
                try:
                    u, v = texture_axes(normals[k], hint, rotation)
                except ValueError as exc:
                    raise self.fail(f"{fwhere}.texture_plane.u_axis", str(exc)) from exc
                tex_map[k, 0] = [*u, -float(u @ origin)]
                tex_map[k, 1] = [*v, -float(v @ origin)]
            if corner_normals is not None:
                vnorm[k] = corner_normals[k][:3]
                try:
                    basis[k] = gouraud_basis(vertices[indices[k][:3]])
                except ValueError as exc:
                    raise self.fail(f"{fwhere}.indices", str(exc)) from exc
        return FaceSurfaces(look, tex_map, vnorm, basis)

    def face_layer(self, face: dict, k: int, layers: list, plane_vertex: list, flat: list,
                   start: list, vertices: np.ndarray, normals: list,
                   where: str) -> tuple[int, int]:
        """(layer, plane vertex) of face k; a face "on" another takes over its plane.

        The face's normal (normals[k]) is replaced by the base face's so that both transform
        to the same eye-space plane bit for bit (geometry.to_eye).
        """
        own_first = flat[start[k]]
        if "on" not in face:
            if "layer" in face:
                raise self.fail(f"{where}.layer", "a layer needs \"on\": the index of the face it lies on")
            return 0, own_first
        base = face["on"]
        if isinstance(base, bool) or not isinstance(base, int) or not 0 <= base < k:
            raise self.fail(f"{where}.on", f"expected the index of an earlier face of this model "
                                           f"(0..{k - 1}), got {_show(base)}")
        layer = face.get("layer", 1)
        if isinstance(layer, bool) or not isinstance(layer, int) or not 1 <= layer <= 1000:
            raise self.fail(f"{where}.layer", f"expected an integer in 1..1000, got {_show(layer)}")
        if layer <= layers[base]:
            raise self.fail(f"{where}.layer", f"{layer} must be above the layer of face {base} ({layers[base]})")
        n = normals[base]
        p0 = vertices[flat[start[base]]]
        pts = vertices[flat[start[k]:start[k + 1]]]
        off = float(np.abs((pts - p0) @ n).max())
        size = float(np.ptp(pts, axis=0).max())
        if off > 1e-3 + 1e-3 * size:
            raise self.fail(f"{where}.on", f"the face is not on face {base} (a vertex lies {off:.4g} m off its plane)")
        if float(normals[k] @ n) <= 0.0:
            raise self.fail(f"{where}.on", f"the face faces away from face {base}")
        normals[k] = n
        # The plane point of the base (its root's first vertex when the base is itself "on"
        # another face), so a whole stack of layers shares one plane.
        return layer, plane_vertex[base]

    def face_normal(self, pts: np.ndarray, where: str) -> np.ndarray:
        """Newell normal of a face; checks it is planar and strictly convex."""
        nxt = np.roll(pts, -1, axis=0)
        newell = np.array([
            np.sum((pts[:, 1] - nxt[:, 1]) * (pts[:, 2] + nxt[:, 2])),
            np.sum((pts[:, 2] - nxt[:, 2]) * (pts[:, 0] + nxt[:, 0])),
            np.sum((pts[:, 0] - nxt[:, 0]) * (pts[:, 1] + nxt[:, 1])),
        ])
        length = float(np.linalg.norm(newell))
        size = float(np.ptp(pts, axis=0).max())
        # Guard: a face with (near) zero area has no normal; reject instead of dividing by ~0.
        if length <= 1e-12 * max(size, 1.0) ** 2:
            raise self.fail(where, "the face has no area (its vertices are collinear or coincide)")
        n = newell / length
        off_plane = np.abs((pts - pts.mean(axis=0)) @ n).max()
        if off_plane > 1e-3 + 1e-3 * size:
            raise self.fail(where, f"the face is not planar (a vertex lies {off_plane:.4g} m off its plane)")
        edges = nxt - pts
        turns = np.cross(edges, np.roll(edges, -1, axis=0)) @ n
        if np.any(turns < -1e-9 * max(size, 1.0) ** 2):
            raise self.fail(where, "the face is not convex, or its winding is not consistent")
        return n


def _show(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, float) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
