"""Floor plan -> textured 3D mesh: walls, furniture, floor and ceiling.

Walls are found on a raster of the plan's free space: every boundary between a free and a solid
cell is a piece of wall surface, runs of them along one grid line are merged into segments, and
each segment becomes vertical quads facing the free side. Each quad (panel) gets a texture of its
own, drawn from the seed, so that places in the building can be told apart; the look-alike zones
of the plan are the deliberate exception.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from longslam.world import textures as tex
from longslam.world.layout import FloorPlan, Rect
from longslam.world.world_mesh import WorldMesh

MAX_PANEL = 4.0  # metres: longest wall panel with one texture
JAMB = 0.35  # metres: wall segments shorter than this are door jambs
FLOOR_QUAD = 4.0  # metres: side of the floor and ceiling quads
_EPS = 1e-6

# Separate random streams, so adding furniture does not change the walls' look.
_WALLS, _PAINT, _FURNITURE, _FLOOR, _DOOR = 1, 2, 3, 4, 5


@dataclass(frozen=True)
class WallSegment:
    """A straight run of wall surface. `axis` 0: the wall runs along x at y = `fixed`; axis 1: it
    runs along y at x = `fixed`. `normal_sign` is +1 if the free side is towards larger
    `fixed`, else -1."""

    axis: int
    fixed: float
    start: float
    end: float
    normal_sign: int

    @property
    def length(self) -> float:
        return self.end - self.start

    @property
    def normal(self) -> np.ndarray:
        n = np.zeros(2)
        n[1 - self.axis] = self.normal_sign
        return n

    def point(self, s: float) -> np.ndarray:
        """World (x, y) of the point at `s` along the axis."""
        p = np.empty(2)
        p[self.axis], p[1 - self.axis] = s, self.fixed
        return p

    @property
    def u_along_axis(self) -> bool:
        """Whether texture u grows with `s`: u runs to the right of someone facing the wall from
        the free side, i.e. along (-ny, nx), so text on the walls reads the right way round."""
        n = self.normal
        return (-n[1], n[0])[self.axis] > 0


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of True along axis 1: (line index, start, end exclusive) per run."""
    d = np.diff(np.pad(mask, ((0, 0), (1, 1))).astype(np.int8), axis=1)
    starts, ends = np.argwhere(d == 1), np.argwhere(d == -1)  # both row-major, so they pair up
    return starts[:, 0], starts[:, 1], ends[:, 1]


def wall_segments(free: np.ndarray, origin: tuple[float, float], resolution: float) -> list[WallSegment]:
    """Every maximal straight run of boundary between free and solid cells of `free`
    ((rows, cols) bool, row i covering y in [oy + i*res, oy + (i+1)*res))."""
    ox, oy = origin
    padded = np.pad(free, 1)
    segments: list[WallSegment] = []
    # Lines y = oy + k*res between padded rows k and k+1; positions are original columns.
    lower, upper = padded[:-1, 1:-1], padded[1:, 1:-1]
    # Lines x = ox + k*res between padded columns k and k+1, transposed so runs go along axis 1.
    left, right = padded[1:-1, :-1].T, padded[1:-1, 1:].T
    for axis, a, b, fixed0, along0 in ((0, lower, upper, oy, ox), (1, left, right, ox, oy)):
        for sign, mask in ((-1, a & ~b), (+1, ~a & b)):
            line, s0, s1 = _runs(mask)
            for k, i, j in zip(line.tolist(), s0.tolist(), s1.tolist()):
                segments.append(
                    WallSegment(axis, fixed0 + k * resolution, along0 + i * resolution, along0 + j * resolution, sign)
                )
    return segments


@dataclass
class _Panel:
    segment: WallSegment
    start: float
    end: float
    zone: tuple[int, int] | None = None  # (pair index, 0 for the original zone or 1 for its look-alike)
    image: int = -1
    u_start: float = 0.0  # texture u (local to the image) at `start` and at `end`
    u_end: float = 0.0


def _zone_span(rect: Rect, axis: int) -> tuple[float, float, float, float]:
    """(along min, along max, across min, across max) of a zone for walls running along `axis`."""
    if axis == 0:
        return rect.xmin, rect.xmax, rect.ymin, rect.ymax
    return rect.ymin, rect.ymax, rect.xmin, rect.xmax


def _split_panels(seg: WallSegment, zones: list[tuple[int, int, Rect]]) -> list[_Panel]:
    """Cut a segment into panels of at most MAX_PANEL. Inside a look-alike zone the cuts lie on a
    grid anchored at the zone's corner, so both zones of a pair are cut at the same offsets."""
    cuts = {seg.start, seg.end}
    for _, _, rect in zones:
        a0, a1, c0, c1 = _zone_span(rect, seg.axis)
        if c0 - _EPS <= seg.fixed <= c1 + _EPS and a0 < seg.end and a1 > seg.start:
            grid = a0 + MAX_PANEL * np.arange(int(math.ceil((a1 - a0) / MAX_PANEL)) + 1)
            cuts.update(float(g) for g in np.append(grid, a1) if seg.start < g < seg.end)
    bounds = sorted(cuts)
    panels = []
    for p0, p1 in zip(bounds[:-1], bounds[1:]):
        mid = (p0 + p1) / 2
        zone = None
        for pair, which, rect in zones:
            a0, a1, c0, c1 = _zone_span(rect, seg.axis)
            if c0 - _EPS <= seg.fixed <= c1 + _EPS and a0 <= mid <= a1:
                zone = (pair, which)
                break
        n = 1 if zone is not None else max(1, int(math.ceil((p1 - p0) / MAX_PANEL - 1e-9)))
        edges = np.linspace(p0, p1, n + 1)
        panels += [_Panel(seg, float(e0), float(e1), zone) for e0, e1 in zip(edges[:-1], edges[1:])]
    return panels


class _Quads:
    """Accumulates textured quads (4 corners counter-clockwise seen from the front)."""

    def __init__(self) -> None:
        self.corners: list[np.ndarray] = []
        self.uvs: list[np.ndarray] = []
        self.images: list[int] = []

    def add(self, corners: np.ndarray, uvs: np.ndarray, image: int) -> None:
        self.corners.append(np.asarray(corners, dtype=np.float64))
        self.uvs.append(np.asarray(uvs, dtype=np.float64))
        self.images.append(image)

    def vertical(
        self,
        p_left: np.ndarray,
        p_right: np.ndarray,
        z0: float,
        z1: float,
        u_left: float,
        u_right: float,
        image_h: int,
        image: int,
    ) -> None:
        """A vertical quad seen from its front with `p_left` on the left; texture rows run from
        the top (z1) down."""
        corners = [(*p_left, z0), (*p_right, z0), (*p_right, z1), (*p_left, z1)]
        v_bottom, v_top = image_h - 0.5, 0.5
        self.add(corners, [(u_left, v_bottom), (u_right, v_bottom), (u_right, v_top), (u_left, v_top)], image)

    def mesh(self, atlas: tex.Atlas) -> WorldMesh:
        corners = np.stack(self.corners)  # (Q, 4, 3)
        uvs = np.stack(self.uvs) + atlas.offsets[np.asarray(self.images)][:, None, :]  # (Q, 4, 2)
        q = len(corners)
        base = 4 * np.arange(q, dtype=np.int32)[:, None]
        triangles = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]], axis=0)
        quad_of_tri = np.concatenate([np.arange(q), np.arange(q)])
        corner_of_tri = np.array([[0, 1, 2]] * q + [[0, 2, 3]] * q)
        tri_uvs = uvs[quad_of_tri[:, None], corner_of_tri]
        # Keep each quad's two triangles together, which keeps memory access local when rendering.
        order = np.argsort(quad_of_tri, kind="stable")
        return WorldMesh(corners.reshape(-1, 3), triangles[order], tri_uvs[order].astype(np.float32), atlas.image)


def _paint_for(plan: FloorPlan, seg: WallSegment, seed: int) -> tuple[int, int, int]:
    """One paint per room; all corridors share one, as in most buildings."""
    front = seg.point((seg.start + seg.end) / 2) + seg.normal * 0.01
    for i, r in enumerate(plan.free):
        if r.xmin <= front[0] <= r.xmax and r.ymin <= front[1] <= r.ymax and r.kind != "door":
            key = 0 if r.kind == "corridor" else i + 1
            rng = np.random.default_rng([seed, _PAINT, key])
            return tex.WALL_PAINTS[int(rng.integers(len(tex.WALL_PAINTS)))]
    return tex.WALL_PAINTS[0]


def _wall_textures(plan: FloorPlan, seed: int, panels: list[_Panel], images: list[np.ndarray]) -> None:
    """Give every panel an image and u range: door jambs share the door-frame texture, panels of
    a look-alike zone borrow from the panel at the same offset of the original zone, the rest get
    a fresh design each."""
    h_m = plan.wall_height
    door = len(images)
    images.append(tex.door_frame(np.random.default_rng([seed, _DOOR]), JAMB, h_m))
    door_w = images[door].shape[1]
    pairs = plan.lookalike_pairs

    def fresh(i: int, p: _Panel) -> None:
        rng = np.random.default_rng([seed, _WALLS, i])
        p.image = len(images)
        images.append(tex.wall_panel(rng, p.end - p.start, h_m, _paint_for(plan, p.segment, seed)))
        w = images[p.image].shape[1]
        lo, hi = 0.5, w - 0.5
        p.u_start, p.u_end = (lo, hi) if p.segment.u_along_axis else (hi, lo)

    originals = [p for p in panels if p.zone is not None and p.zone[1] == 0]
    for i, p in enumerate(panels):
        seg = p.segment
        if seg.length < JAMB:
            p.image = door
            span = (door_w - 1) * (p.end - p.start) / JAMB
            p.u_start, p.u_end = (0.5, 0.5 + span) if seg.u_along_axis else (0.5 + span, 0.5)
        elif p.zone is None or p.zone[1] == 0:
            fresh(i, p)
    for i, p in enumerate(panels):
        if p.zone is None or p.zone[1] != 1 or p.image >= 0:
            continue
        seg = p.segment
        a_rect, b_rect = pairs[p.zone[0]]
        a0, _, ac0, _ = _zone_span(a_rect, seg.axis)
        b0, _, bc0, _ = _zone_span(b_rect, seg.axis)
        # The same place relative to the original zone.
        fixed, s0, s1 = seg.fixed - bc0 + ac0, p.start - b0 + a0, p.end - b0 + a0
        match = next(
            (
                o
                for o in originals
                if o.zone is not None
                and o.zone[0] == p.zone[0]
                and o.segment.axis == seg.axis
                and o.segment.normal_sign == seg.normal_sign
                and abs(o.segment.fixed - fixed) < 1e-3
                and o.start - 1e-3 <= s0
                and s1 <= o.end + 1e-3
                and o.image >= 0
            ),
            None,
        )
        if match is None:  # the original zone has an opening here: nothing to copy
            fresh(i, p)
            continue
        p.image = match.image
        scale = (match.u_end - match.u_start) / (match.end - match.start)
        p.u_start = match.u_start + (s0 - match.start) * scale
        p.u_end = match.u_start + (s1 - match.start) * scale


def _add_walls(quads: _Quads, panels: list[_Panel], images: list[np.ndarray], height: float) -> None:
    for p in panels:
        seg = p.segment
        a, b = seg.point(p.start), seg.point(p.end)
        h = images[p.image].shape[0]
        if seg.u_along_axis:  # start is on the viewer's left
            quads.vertical(a, b, 0.0, height, p.u_start, p.u_end, h, p.image)
        else:
            quads.vertical(b, a, 0.0, height, p.u_end, p.u_start, h, p.image)


def _add_furniture(quads: _Quads, plan: FloorPlan, seed: int, images: list[np.ndarray]) -> None:
    for i, box in enumerate(plan.furniture):
        rng = np.random.default_rng([seed, _FURNITURE, i])
        x0, y0, x1, y1, h = box.xmin, box.ymin, box.xmax, box.ymax, box.height
        # Sides seen from outside, each as (left corner, right corner).
        sides = [((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)), ((x1, y1), (x0, y1)), ((x0, y1), (x0, y0))]
        for left, right in sides:
            length = math.dist(left, right)
            img = tex.furniture_side(rng, length, h, box.kind)
            quads.vertical(np.array(left), np.array(right), 0.0, h, 0.5, img.shape[1] - 0.5, img.shape[0], len(images))
            images.append(img)
        if h < plan.wall_height - _EPS:  # a pillar's top is hidden in the ceiling
            colour = (110, 84, 60) if box.kind == "desk" else (186, 146, 98)
            img = tex.wood(rng, x1 - x0, y1 - y0, colour)
            hh, ww = img.shape[:2]
            quads.add(
                [(x0, y0, h), (x1, y0, h), (x1, y1, h), (x0, y1, h)],
                [(0.5, hh - 0.5), (ww - 0.5, hh - 0.5), (ww - 0.5, 0.5), (0.5, 0.5)],
                len(images),
            )
            images.append(img)


def _add_floor_and_ceiling(
    quads: _Quads,
    plan: FloorPlan,
    seed: int,
    free: np.ndarray,
    resolution: float,
    images: list[np.ndarray],
    variants: int = 4,
) -> None:
    """A grid of FLOOR_QUAD squares over the plan, skipping squares with no free space under them.
    A few texture variants per surface, picked at random per square, keep the floor from
    repeating every 4 m while the atlas stays small."""
    rng = np.random.default_rng([seed, _FLOOR])
    kinds = {
        "floor": [tex.floor_tiles(rng) for _ in range(variants)],
        "hall_floor": [tex.hall_floor(rng) for _ in range(variants)],
        "ceiling": [tex.ceiling_panels(rng) for _ in range(variants)],
        "hall_ceiling": [tex.ceiling_panels(rng, hall=True) for _ in range(variants)],
    }
    ids = {}
    for name, imgs in kinds.items():
        ids[name] = list(range(len(images), len(images) + len(imgs)))
        images.extend(imgs)
    size_px = images[ids["floor"][0]].shape[0]
    scale = (size_px - 1) / FLOOR_QUAD  # texture u per metre, texel centres at the quad's corners
    halls = [r for r in plan.free if r.kind == "hall"]
    bx0, by0, bx1, by1 = plan.bounds
    zc = plan.wall_height
    for gy in range(int(math.ceil((by1 - by0) / FLOOR_QUAD - 1e-9))):
        for gx in range(int(math.ceil((bx1 - bx0) / FLOOR_QUAD - 1e-9))):
            x0, y0 = bx0 + gx * FLOOR_QUAD, by0 + gy * FLOOR_QUAD
            x1, y1 = min(x0 + FLOOR_QUAD, bx1), min(y0 + FLOOR_QUAD, by1)
            r0, r1 = int(round((y0 - by0) / resolution)), int(round((y1 - by0) / resolution))
            c0, c1 = int(round((x0 - bx0) / resolution)), int(round((x1 - bx0) / resolution))
            if not free[r0:r1, c0:c1].any():
                continue
            cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
            hall = any(r.xmin <= cx <= r.xmax and r.ymin <= cy <= r.ymax for r in halls)
            # u along +x; v (rows) along -y, so the texture is upright seen from above.
            u0, u1 = 0.5, 0.5 + (x1 - x0) * scale
            v_top, v_bottom = 0.5, 0.5 + (y1 - y0) * scale
            floor_img = ids["hall_floor" if hall else "floor"][int(rng.integers(variants))]
            ceil_img = ids["hall_ceiling" if hall else "ceiling"][int(rng.integers(variants))]
            quads.add(
                [(x0, y0, 0.0), (x1, y0, 0.0), (x1, y1, 0.0), (x0, y1, 0.0)],
                [(u0, v_bottom), (u1, v_bottom), (u1, v_top), (u0, v_top)],
                floor_img,
            )
            quads.add(
                [(x0, y0, zc), (x0, y1, zc), (x1, y1, zc), (x1, y0, zc)],
                [(u0, v_bottom), (u0, v_top), (u1, v_top), (u1, v_bottom)],
                ceil_img,
            )


def build_mesh(plan: FloorPlan, seed: int = 0, resolution: float = 0.05) -> WorldMesh:
    """The textured mesh of a floor plan. Same plan and seed give an identical mesh.

    `resolution` is the raster used to find the walls: plan coordinates should be multiples of it.
    """
    free = plan.free_mask(resolution)
    segments = wall_segments(free, (plan.bounds[0], plan.bounds[1]), resolution)
    zones = [(i, which, pair[which]) for i, pair in enumerate(plan.lookalike_pairs) for which in (0, 1)]
    panels = [p for seg in segments for p in _split_panels(seg, zones)]
    images: list[np.ndarray] = []
    _wall_textures(plan, seed, panels, images)
    quads = _Quads()
    _add_walls(quads, panels, images, plan.wall_height)
    _add_furniture(quads, plan, seed, images)
    _add_floor_and_ceiling(quads, plan, seed, free, resolution, images)
    return quads.mesh(tex.pack_atlas(images))
