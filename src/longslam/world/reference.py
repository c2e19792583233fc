"""A world given by name or as a mesh file, as one reference string that travels with a route.

A world reference is a registered world's name (`university`) or, for a user's building, `mesh:`
followed by a JSON object: the mesh file's absolute path, the SHA-256 of its content (with the
material and texture files it names) and its options (floor height, units, up axis, places).
The hash pins the content: the render cache and a study's run configurations change when the
mesh is edited, and a process that finds other content at the path refuses it rather than
mixing two buildings in one study.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import re
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from longslam.core.errors import InputError
from longslam.core.textfile import read_text
from longslam.world.catalog import WORLDS, get_world
from longslam.world.mesh_reader import MESH_SUFFIXES
from longslam.world.model import World
from longslam.world.own_building import UNITS, UP_AXES, default_up, load_mesh_world

MESH_PREFIX = "mesh:"
OPTION_KEYS = ("mesh", "floor", "units", "up", "places")


@dataclass(frozen=True)
class MeshSpec:
    """A user's mesh world: where the file is, what it holds, and how to read it."""

    path: str  # absolute
    sha256: str  # of the file and the files it names (materials, textures, buffers)
    floor: float | None = None  # metres after turning z-up; None: found automatically
    units: str = "m"
    up: str = "z"
    places: tuple[tuple[str, float, float], ...] = ()
    # Where the places were read from (absolute), for messages about them; like `path`, not part of
    # the content, and left out of the reference when there is none (the references made before).
    places_file: str = ""

    def ref(self) -> str:
        data = asdict(self)
        if not data["places_file"]:
            del data["places_file"]
        return MESH_PREFIX + json.dumps(data, sort_keys=True, separators=(",", ":"))

    @classmethod
    def from_ref(cls, ref: str) -> "MeshSpec":
        data = json.loads(ref[len(MESH_PREFIX) :])
        data["places"] = tuple(tuple(p) for p in data.get("places", ()))
        return cls(**data)

    @property
    def content(self) -> str:
        """Everything that makes the world what it is, without where the file happens to be."""
        data = asdict(self)
        data.pop("path")
        data.pop("places_file")
        return json.dumps(data, sort_keys=True, separators=(",", ":"))

    @property
    def key(self) -> str:
        """A file-name-safe name: the file's stem and a hash of its content and options."""
        stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(self.path).stem) or "mesh"
        return f"{stem}-{hashlib.sha256(self.content.encode()).hexdigest()[:12]}"


def is_mesh_ref(ref: str) -> bool:
    return ref.startswith(MESH_PREFIX)


def world_ref(value: Any, base: Path | None = None, what: str = "world") -> str:
    """The reference of a world given as a registered name, a mesh file's path (relative to
    `base`), or a table {"mesh": path, "floor": z, "units": "mm", "up": "y", "places": file}.
    An existing reference is returned as it is. Errors name `what`."""
    if isinstance(value, dict):
        unknown = [k for k in value if k not in OPTION_KEYS]
        if unknown:
            raise InputError(f"{what}: unknown key {unknown[0]!r}; valid keys: {', '.join(OPTION_KEYS)}")
        if not isinstance(value.get("mesh"), str):
            raise InputError(f"{what}: expected 'mesh' = the path of a mesh file, got {value.get('mesh')!r}")
        options = {k: v for k, v in value.items() if k != "mesh"}
        return mesh_world_ref(value["mesh"], base=base, what=what, **options)
    if not isinstance(value, str) or not value:
        raise InputError(f"{what}: expected a world name or a mesh file, got {value!r}")
    if value in WORLDS or is_mesh_ref(value):
        return value
    path = _resolve(value, base)
    if path.is_file() or Path(value).suffix.lower() in MESH_SUFFIXES or "/" in value:
        return mesh_world_ref(value, base=base, what=what)
    from longslam.core.suggest import did_you_mean

    raise InputError(
        f"{what}: unknown world {value!r}{did_you_mean(value, WORLDS.names())}; valid values: a world name "
        f"({', '.join(WORLDS.names())}) "
        f"or a mesh file ({', '.join(s.lstrip('.').upper() for s in MESH_SUFFIXES)})"
    )


def mesh_world_ref(
    path: str | Path,
    floor: Any = None,
    units: Any = "m",
    up: Any = None,
    places: Any = None,
    base: Path | None = None,
    what: str = "world",
) -> str:
    """The reference of a mesh world, its options checked and its content hashed."""
    file = _resolve(path, base)
    if file.is_dir():
        raise InputError(f"{what}: mesh file {file} is a folder; expected a mesh file (PLY, OBJ or GLB)")
    if not file.is_file():
        raise InputError(f"{what}: mesh file {file} does not exist")
    if floor is not None and (
        isinstance(floor, bool) or not isinstance(floor, (int, float)) or not math.isfinite(floor)
    ):
        raise InputError(f"{what}: floor must be a height in metres, got {floor!r}")
    if units not in UNITS:
        raise InputError(f"{what}: unknown units {units!r}; valid values: {', '.join(UNITS)}")
    up = default_up(file) if up is None else up
    if up not in UP_AXES:
        raise InputError(f"{what}: unknown up axis {up!r}; valid values: {', '.join(UP_AXES)}")
    place_list: tuple = ()
    places_file = ""
    if places is not None:
        if not isinstance(places, (str, Path)):
            raise InputError(f"{what}: places must be the path of a places file (JSON), got {places!r}")
        places_path = _resolve(places, base)
        found = read_places(places_path)
        place_list = tuple((name, x, y) for name, (x, y) in sorted(found.items()))
        places_file = str(places_path.absolute())
    spec = MeshSpec(
        str(file), content_hash(file), None if floor is None else float(floor), units, up, place_list, places_file
    )
    return spec.ref()


def read_places(path: Path) -> dict[str, tuple[float, float]]:
    """Named spots on the floor from a JSON object {"name": [x, y], ...} (metres)."""
    text = read_text(path, "places file")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise InputError(f"places file {path}: not valid JSON ({err})") from None
    if isinstance(data, dict) and not data:  # a tour or a named waypoint needs a place to stand on
        raise InputError(f'places file {path}: has no places; expected at least one, {{"name": [x, y], ...}} in metres')
    if not isinstance(data, dict):
        raise InputError(f'places file {path}: expected an object {{"name": [x, y], ...}}, got {text[:60]!r}')
    places = {}
    for name, xy in data.items():
        if not (
            isinstance(xy, list)
            and len(xy) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in xy)
        ):
            raise InputError(f"places file {path}: {name!r} = {xy!r}; expected [x, y] in metres")
        places[name] = (float(xy[0]), float(xy[1]))
    return places


def content_hash(path: Path) -> str:
    """SHA-256 over the mesh file and the files it names, so an edited texture counts too."""
    digest = hashlib.sha256()
    for file in [path, *_companions(path)]:
        digest.update(file.name.encode() + b"\0")
        with open(file, "rb") as handle:
            for block in iter(lambda: handle.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()


def _companions(path: Path) -> list[Path]:
    """The existing files a mesh file refers to: OBJ materials and their maps, glTF buffers and
    images, a PLY's TextureFile. Binary formats (GLB) carry everything inside."""
    suffix = path.suffix.lower()
    names: list[str] = []
    try:
        if suffix == ".obj":
            for line in path.read_text(errors="replace").splitlines():
                if line.startswith("mtllib"):
                    names += line.split(None, 1)[1:]
            for mtl in list(names):
                mtl_path = path.parent / mtl.strip()
                if mtl_path.is_file():
                    for line in mtl_path.read_text(errors="replace").splitlines():
                        fields = line.split()
                        if fields and fields[0].lower().startswith(("map_", "bump", "disp", "norm")):
                            names.append(fields[-1])
        elif suffix == ".gltf":
            data = json.loads(path.read_text(encoding="utf-8"))
            names += [
                item["uri"]
                for key in ("buffers", "images")
                for item in data.get(key, [])
                if isinstance(item.get("uri"), str) and not item["uri"].startswith("data:")
            ]
        elif suffix == ".ply":
            with open(path, "rb") as handle:
                for raw in iter(handle.readline, b""):
                    line = raw.decode("latin-1").strip()
                    if line.startswith("comment TextureFile"):
                        names.append(line.split(None, 2)[2])
                    if line == "end_header" or len(raw) > 10_000:
                        break
    except (OSError, ValueError, UnicodeDecodeError):
        return []
    files = []
    for name in names:
        file = path.parent / name.strip()
        if file.is_file() and file not in files:
            files.append(file)
    return files


def _resolve(path: str | Path, base: Path | None) -> Path:
    path = Path(path).expanduser()
    if not path.is_absolute() and base is not None:
        path = Path(base) / path
    return path.absolute()


def load_world(ref: str) -> World:
    """The world of a reference: a registered world, or the mesh world after checking that the
    file still holds the content the reference was made from."""
    if not is_mesh_ref(ref):
        return get_world(ref)
    spec = MeshSpec.from_ref(ref)
    path = Path(spec.path)
    if not path.is_file():
        raise InputError(f"mesh file {path} (world {spec.key}) does not exist on this machine")
    now = content_hash(path)
    if now != spec.sha256:
        raise InputError(
            f"mesh file {path} has changed since this world was given (sha256 {spec.sha256[:12]}, now {now[:12]}); "
            "give the world again so that everything is made from one content"
        )
    return _load_mesh(ref)


@functools.lru_cache(maxsize=2)  # a mesh world can take hundreds of MB: keep few
def _load_mesh(ref: str) -> World:
    spec = MeshSpec.from_ref(ref)
    places = {name: (x, y) for name, x, y in spec.places}
    return load_mesh_world(
        spec.path, spec.floor, name=Path(spec.path).stem, units=spec.units, up=spec.up, places=places
    )


def world_key(ref: str) -> str:
    """A name for file names and cache keys: the world's name, or the mesh's stem and hash."""
    return MeshSpec.from_ref(ref).key if is_mesh_ref(ref) else ref


def world_label(ref: str) -> str:
    """How to show the world to people: its name, or its mesh file's name."""
    return Path(MeshSpec.from_ref(ref).path).name if is_mesh_ref(ref) else ref


def places_label(ref: str) -> str:
    """Where a world's places come from, for messages: its places file, or the world."""
    if is_mesh_ref(ref):
        spec = MeshSpec.from_ref(ref)
        return f"places file {spec.places_file}" if spec.places_file else f"world {Path(spec.path).name!r}"
    return f"world {ref!r}"


def world_identity(ref: str) -> str:
    """What makes the world what it is (for cache keys and run hashes): its name, or its mesh's
    content and options, not the path where the file lies."""
    return MeshSpec.from_ref(ref).content if is_mesh_ref(ref) else ref


def same_world(a: str, b: str) -> bool:
    return world_identity(a) == world_identity(b)
