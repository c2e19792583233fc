"""Procedural textures for the simulated building, and the atlas they are packed into.

Every texture is drawn from an explicit `numpy.random.Generator`, so a seed fixes the building's
look. The designs aim at what feature-based SLAM needs from a real building: corners, edges and
contrast (posters with shapes and text, signs, tile grout, light fixtures), while plain painted
wall between them keeps the images from being unrealistically busy.

Images are RGB uint8, row 0 at the top. Resolution is `PX_PER_M` texels per metre (2 cm each).
"""

from __future__ import annotations

import math
import string
from dataclasses import dataclass

import cv2
import numpy as np

PX_PER_M = 50.0

# Pale paints for corridor and room walls.
WALL_PAINTS = [
    (226, 222, 210),
    (214, 222, 228),
    (232, 226, 200),
    (222, 214, 224),
    (208, 222, 208),
    (234, 234, 230),
    (238, 220, 204),
    (218, 226, 218),
    (226, 216, 204),
]
_LETTERS = string.ascii_uppercase + string.digits


def texels(metres: float, ppm: float = PX_PER_M) -> int:
    return max(1, int(math.ceil(metres * ppm - 1e-6)))


def _colour(rng: np.random.Generator, lo: int = 0, hi: int = 256) -> tuple[int, int, int]:
    c = rng.integers(lo, hi, 3)
    return int(c[0]), int(c[1]), int(c[2])


def _vivid(rng: np.random.Generator) -> tuple[int, int, int]:
    """A saturated colour: one channel high, one low, so shapes stand out of their background."""
    c = rng.integers(0, 256, 3)
    order = rng.permutation(3)
    c[order[0]] = rng.integers(170, 256)
    c[order[1]] = rng.integers(0, 80)
    return int(c[0]), int(c[1]), int(c[2])


def _noisy_fill(
    rng: np.random.Generator, h: int, w: int, colour, grain: float = 4.0, blotch: float = 5.0
) -> np.ndarray:
    """A flat colour with per-texel grain and low-frequency blotches (real paint is never flat)."""
    img = np.empty((h, w, 3), dtype=np.float32)
    img[:] = np.asarray(colour, dtype=np.float32)
    if blotch > 0:
        small = rng.normal(0.0, blotch, (h // 20 + 2, w // 20 + 2)).astype(np.float32)
        img += cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)[:, :, None]
    if grain > 0:
        img += rng.normal(0.0, grain, (h, w, 1)).astype(np.float32)
    return np.clip(img, 0, 255).astype(np.uint8)


def _random_text(rng: np.random.Generator, n: int) -> str:
    return "".join(rng.choice(list(_LETTERS), n))


def _text_rows(rng: np.random.Generator, img: np.ndarray, x0: int, y0: int, x1: int, y1: int, colour) -> None:
    """Rows of word-like dark bars, what small print looks like at a distance."""
    y = y0
    while y + 2 <= y1:
        x = x0 + int(rng.integers(0, 3))
        while True:
            length = int(rng.integers(3, 14))
            if x + length > x1:
                break
            img[y : y + 2, x : x + length] = colour
            x += length + int(rng.integers(2, 4))
        y += int(rng.integers(4, 6))


def _put_text(img: np.ndarray, text: str, x: int, baseline: int, height: int, colour) -> None:
    scale = cv2.getFontScaleFromHeight(cv2.FONT_HERSHEY_SIMPLEX, max(3, height), 1)
    cv2.putText(img, text, (x, baseline), cv2.FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv2.LINE_8)


# Each item below draws on its own canvas of the item's size, which keeps shapes inside it.


def _poster(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    bg = _colour(rng, 150, 256) if rng.random() < 0.6 else _vivid(rng)
    img = np.empty((h, w, 3), dtype=np.uint8)
    img[:] = bg
    dark = tuple(int(c) for c in rng.integers(0, 70, 3))
    # A title in real letters, a picture of random shapes, then small print.
    title_h = max(5, h // 7)
    _put_text(img, _random_text(rng, int(rng.integers(3, 8))), 2, title_h + 1, title_h - 1, dark)
    py0, py1 = title_h + 3, title_h + 3 + int(h * 0.45)
    if rng.random() < 0.5:
        img[py0:py1, 2 : w - 2] = _colour(rng, 0, 256)
    picture = img[py0:py1, 2 : w - 2].copy()
    ph, pw = picture.shape[:2]
    for _ in range(int(rng.integers(3, 8))):
        if ph < 2 or pw < 2:
            break
        colour = _vivid(rng) if rng.random() < 0.7 else dark
        kind = rng.integers(0, 4)
        cx, cy = int(rng.integers(0, pw)), int(rng.integers(0, ph))
        size = int(rng.integers(2, max(3, min(pw, ph) // 3)))
        if kind == 0:
            cv2.circle(picture, (cx, cy), size, colour, -1, cv2.LINE_8)
        elif kind == 1:
            cv2.rectangle(picture, (cx - size, cy - size // 2), (cx + size, cy + size // 2), colour, -1)
        elif kind == 2:
            pts = rng.integers([0, 0], [pw, ph], (3, 2)).astype(np.int32)
            cv2.fillPoly(picture, [pts], colour, cv2.LINE_8)
        else:
            p = rng.integers([0, 0], [pw, ph], (2, 2))
            cv2.line(
                picture, (int(p[0, 0]), int(p[0, 1])), (int(p[1, 0]), int(p[1, 1])), colour, int(rng.integers(1, 4))
            )
    img[py0:py1, 2 : w - 2] = picture
    _text_rows(rng, img, 3, py1 + 3, w - 3, h - 3, dark)
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), dark, 1)
    return img


def _sign(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    plate = [(20, 90, 40), (30, 60, 140), (240, 240, 235), (200, 40, 30), (250, 200, 40)][int(rng.integers(0, 5))]
    ink = (255, 255, 255) if sum(plate) < 400 else (20, 20, 20)
    img = np.empty((h, w, 3), dtype=np.uint8)
    img[:] = plate
    text_h = max(4, int(h * 0.55))
    arrow = rng.random() < 0.5  # as on direction signs
    room = w - 4 - (h if arrow else 0)
    n = max(1, min(8, room // max(4, int(text_h * 0.9))))
    _put_text(img, _random_text(rng, n), 2, h - max(2, (h - text_h) // 2), text_h, ink)
    if arrow:
        ay = h // 2
        cv2.arrowedLine(img, (w - 3, ay), (max(0, w - 3 - h), ay), ink, 1, cv2.LINE_8, tipLength=0.4)
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), (40, 40, 40), 1)
    return img


def _pattern(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A decorative panel: stripes, a checkerboard, dots or diagonals in two contrasting colours."""
    a, b = _colour(rng, 120, 256), _colour(rng, 0, 110)
    yy, xx = np.mgrid[0:h, 0:w]
    period = int(rng.integers(5, 16))
    kind = int(rng.integers(0, 4))
    if kind == 0:
        mask = (xx // period) % 2 == 0 if rng.random() < 0.5 else (yy // period) % 2 == 0
    elif kind == 1:
        mask = ((xx // period) + (yy // period)) % 2 == 0
    elif kind == 2:
        mask = ((xx % period - period / 2) ** 2 + (yy % period - period / 2) ** 2) < (period / 3) ** 2
    else:
        mask = ((xx + yy) // period) % 2 == 0
    img = np.empty((h, w, 3), dtype=np.uint8)
    img[:] = a
    img[mask] = b
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), (50, 50, 50), 1)
    return img


def _notice_board(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    img = _noisy_fill(rng, h, w, (176, 132, 86), grain=10, blotch=4)
    for _ in range(int(rng.integers(3, 9))):
        pw, ph = int(rng.integers(8, 16)), int(rng.integers(10, 20))
        if w - 4 <= pw or h - 4 <= ph:
            continue
        px, py = int(rng.integers(2, w - 2 - pw)), int(rng.integers(2, h - 2 - ph))
        paper = [(250, 250, 245), (250, 240, 150), (250, 200, 210), (190, 230, 250)][int(rng.integers(0, 4))]
        img[py : py + ph, px : px + pw] = paper
        _text_rows(rng, img, px + 1, py + 2, px + pw - 1, py + ph - 1, (40, 40, 60))
        img[py : py + 2, px + pw // 2 - 1 : px + pw // 2 + 1] = _vivid(rng)  # a pin
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), (90, 60, 30), 2)
    return img


def _extinguisher(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    img = np.empty((h, w, 3), dtype=np.uint8)
    img[:] = (190, 20, 20)
    img[3:8, 2 : w - 2] = (240, 240, 240)
    img[h // 2 :, w // 2 - 1 : w // 2 + 1] = (120, 10, 10)
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), (60, 10, 10), 1)
    return img


_ITEMS = {"poster": _poster, "board": _notice_board, "pattern": _pattern, "extinguisher": _extinguisher}
_ITEM_KINDS = ["poster", "board", "pattern", "extinguisher", "blank"]
_ITEM_ODDS = [0.5, 0.15, 0.15, 0.08, 0.12]


def wall_panel(rng: np.random.Generator, width_m: float, height_m: float, paint, ppm: float = PX_PER_M) -> np.ndarray:
    """One wall panel: paint, skirting board, seams at its edges, and a random set of posters,
    notice boards, patterned panels and signs, so that every panel looks different."""
    w, h = texels(width_m, ppm), texels(height_m, ppm)
    img = _noisy_fill(rng, h, w, paint, grain=3.0, blotch=4.0)

    def row(z: float) -> int:
        return int(np.clip(round((height_m - z) * ppm), 0, h))

    skirting = tuple(int(c) for c in rng.integers(40, 90, 3))
    if row(0.12) < h:
        img[row(0.12) :, :] = _noisy_fill(rng, h - row(0.12), w, skirting, grain=3.0, blotch=0.0)
        img[row(0.12), :] = np.asarray(skirting) // 2
    if rng.random() < 0.4:  # a chair rail
        rail = tuple(int(c) for c in rng.integers(60, 160, 3))
        img[row(0.92) : row(0.88), :] = rail
    # Panel seams make corners where they meet the skirting and rail.
    img[:, 0] = (img[:, 0].astype(np.int16) * 3 // 4).astype(np.uint8)
    if w > 1:
        img[:, -1] = (img[:, -1].astype(np.int16) * 3 // 4).astype(np.uint8)

    # Things hung at eye level, left to right.
    x = rng.uniform(0.1, 0.6)
    while x < width_m - 0.4:
        kind = _ITEM_KINDS[rng.choice(len(_ITEM_KINDS), p=_ITEM_ODDS)]
        if kind == "poster":
            iw = rng.uniform(0.5, 1.0)
            bottom, top = rng.uniform(1.1, 1.25), rng.uniform(1.75, 2.0)
        elif kind == "board":
            iw = rng.uniform(0.8, 1.4)
            bottom, top = rng.uniform(1.0, 1.15), rng.uniform(1.8, 2.0)
        elif kind == "pattern":
            iw = rng.uniform(0.5, 1.5)
            bottom, top = (
                (0.25, rng.uniform(0.7, 0.85)) if rng.random() < 0.5 else (rng.uniform(0.3, 0.5), rng.uniform(2.0, 2.5))
            )
        elif kind == "extinguisher":
            iw, bottom, top = 0.2, 0.3, 0.8
        else:
            iw, bottom, top = rng.uniform(0.3, 1.0), 0.0, 0.0
        if x + iw > width_m - 0.1:
            break
        x0, x1 = int(x * ppm), int((x + iw) * ppm)
        y0, y1 = row(top), row(bottom)
        if kind != "blank" and x1 - x0 > 4 and y1 - y0 > 4:
            img[y0:y1, x0:x1] = _ITEMS[kind](rng, y1 - y0, x1 - x0)
        x += iw + rng.uniform(0.15, 0.7)

    # Signs above head height.
    for _ in range(int(rng.integers(0, 3))):
        sw = rng.uniform(0.3, 0.7)
        if sw > width_m - 0.2:
            continue
        sx = rng.uniform(0.1, width_m - sw - 0.1)
        bottom = rng.uniform(2.1, 2.35)
        y0, y1 = row(bottom + rng.uniform(0.14, 0.24)), row(bottom)
        x0, x1 = int(sx * ppm), int((sx + sw) * ppm)
        img[y0:y1, x0:x1] = _sign(rng, y1 - y0, x1 - x0)
    return img


def door_frame(rng: np.random.Generator, width_m: float, height_m: float, ppm: float = PX_PER_M) -> np.ndarray:
    """Dark wood with vertical grain, for door jambs."""
    w, h = texels(width_m, ppm), texels(height_m, ppm)
    grain = rng.normal(0.0, 12.0, (1, w)).astype(np.float32) + rng.normal(0.0, 4.0, (h, w)).astype(np.float32)
    img = np.asarray((92, 58, 34), dtype=np.float32) + grain[:, :, None] * np.asarray(
        (1.0, 0.7, 0.45), dtype=np.float32
    )
    img = np.clip(img, 0, 255).astype(np.uint8)
    img[:, 0] = img[:, -1] = (40, 24, 14)
    return img


def _tile_grid(
    rng: np.random.Generator, size_px: int, tile_px: int, colours: np.ndarray, grout, speckle: float
) -> np.ndarray:
    """Square tiles of `tile_px` texels, tile (i, j) coloured `colours[i, j]`, grout lines between them."""
    img = np.repeat(np.repeat(colours.astype(np.float32), tile_px, 0), tile_px, 1)[:size_px, :size_px]
    img += rng.normal(0.0, 3.0, (size_px, size_px, 1)).astype(np.float32)
    dots = rng.random((size_px, size_px)) < speckle
    img[dots] *= rng.uniform(0.55, 0.85, (int(dots.sum()), 1)).astype(np.float32)
    img = np.clip(img, 0, 255).astype(np.uint8)
    img[::tile_px, :] = grout
    img[:, ::tile_px] = grout
    return img


def floor_tiles(
    rng: np.random.Generator, size_m: float = 4.0, tile_m: float = 0.5, ppm: float = PX_PER_M
) -> np.ndarray:
    """Corridor and room floor: beige 0.5 m tiles, each a slightly different shade, with grout and speckle."""
    size, tile = texels(size_m, ppm), texels(tile_m, ppm)
    n = int(math.ceil(size / tile))
    base = np.asarray((196, 184, 160), dtype=np.float32)
    colours = base + rng.normal(0.0, 14.0, (n, n, 1)) + rng.normal(0.0, 2.5, (n, n, 3))
    return _tile_grid(rng, size, tile, np.clip(colours, 0, 255), (110, 104, 94), speckle=0.04)


def hall_floor(rng: np.random.Generator, size_m: float = 4.0, tile_m: float = 1.0, ppm: float = PX_PER_M) -> np.ndarray:
    """Hall floor: large stone tiles in a dark/light checkerboard with veins, unlike the corridors."""
    size, tile = texels(size_m, ppm), texels(tile_m, ppm)
    n = int(math.ceil(size / tile))
    checker = (np.add.outer(np.arange(n), np.arange(n)) % 2).astype(np.float32)[:, :, None]
    colours = (1 - checker) * np.asarray((92, 96, 104)) + checker * np.asarray((214, 208, 196))
    colours = colours + rng.normal(0.0, 8.0, (n, n, 1))
    img = _tile_grid(rng, size, tile, np.clip(colours, 0, 255), (60, 60, 60), speckle=0.02)
    for _ in range(int(rng.integers(6, 14))):  # marble veins
        pts = np.cumsum(rng.normal(0.0, 6.0, (6, 2)), axis=0) + rng.uniform(0, size, 2)
        grey = int(rng.integers(130, 240))
        cv2.polylines(img, [pts.astype(np.int32)], False, (grey, grey, grey - 6), 1, cv2.LINE_8)
    return img


def ceiling_panels(
    rng: np.random.Generator, size_m: float = 4.0, tile_m: float = 0.5, ppm: float = PX_PER_M, hall: bool = False
) -> np.ndarray:
    """Suspended ceiling: off-white acoustic tiles in a metal grid, with a light fixture or two."""
    size, tile = texels(size_m, ppm), texels(tile_m, ppm)
    n = int(math.ceil(size / tile))
    base = np.asarray((226, 228, 230) if hall else (234, 232, 226), dtype=np.float32)
    colours = base + rng.normal(0.0, 3.0, (n, n, 1))
    img = _tile_grid(rng, size, tile, np.clip(colours, 0, 255), (168, 168, 172), speckle=0.025)
    fixtures = [(0.4, 0.6, 0.3, 0.7)] if not hall else [(0.2, 0.4, 0.2, 0.4), (0.6, 0.8, 0.6, 0.8)]
    if not hall and rng.random() < 0.5:
        fixtures = [(0.3, 0.7, 0.45, 0.55)]
    for fx0, fx1, fy0, fy1 in fixtures:
        x0, x1, y0, y1 = (int(v * size) for v in (fx0, fx1, fy0, fy1))
        img[y0:y1, x0:x1] = (252, 252, 244)
        cv2.rectangle(img, (x0, y0), (x1 - 1, y1 - 1), (120, 120, 125), 1)
        for xl in range(x0 + 4, x1 - 1, 6):  # louvres
            img[y0 + 1 : y1 - 1, xl] = (200, 200, 204)
    return img


def wood(
    rng: np.random.Generator, width_m: float, height_m: float, colour=(186, 146, 98), ppm: float = PX_PER_M
) -> np.ndarray:
    """Wood grain running along the width (table tops)."""
    w, h = texels(width_m, ppm), texels(height_m, ppm)
    grain = rng.normal(0.0, 14.0, (h, 1)).astype(np.float32) + rng.normal(0.0, 5.0, (h, w)).astype(np.float32)
    img = np.asarray(colour, dtype=np.float32) + grain[:, :, None] * np.asarray((1.0, 0.8, 0.6), dtype=np.float32)
    img = np.clip(img, 0, 255).astype(np.uint8)
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), tuple(int(c * 0.55) for c in colour), 1)
    return img


def furniture_side(
    rng: np.random.Generator, width_m: float, height_m: float, kind: str, ppm: float = PX_PER_M
) -> np.ndarray:
    """The side of a table or desk (modesty panel under an edge band) or of a pillar (concrete
    with a poster or sign, so the pillars of a hall can be told apart)."""
    w, h = texels(width_m, ppm), texels(height_m, ppm)
    if kind == "pillar":
        img = _noisy_fill(rng, h, w, (172, 170, 164), grain=6.0, blotch=6.0)
        img[h - texels(0.1, ppm) :, :] = (70, 70, 72)
        # A poster in the middle of the face at eye level.
        top, bottom = int((height_m - 2.0) * ppm), int((height_m - 1.1) * ppm)
        if w > 8 and 0 <= top < bottom <= h:
            img[top:bottom, 2 : w - 2] = _poster(rng, bottom - top, w - 4)
        top, bottom = int((height_m - 2.5) * ppm), int((height_m - 2.3) * ppm)
        if w > 8 and 0 <= top < bottom <= h and rng.random() < 0.7:
            img[top:bottom, 2 : w - 2] = _sign(rng, bottom - top, w - 4)
        return img
    body = (70, 64, 60) if kind == "desk" else tuple(int(c) for c in rng.integers(80, 170, 3))
    img = _noisy_fill(rng, h, w, body, grain=5.0, blotch=3.0)
    band = max(1, texels(0.04, ppm))
    img[:band, :] = (150, 118, 80)
    img[band, :] = (40, 36, 32)
    img[:, :2] = (45, 45, 48)  # legs at the corners
    img[:, -2:] = (45, 45, 48)
    return img


@dataclass
class Atlas:
    """All textures of a mesh in one image. `offsets[i]` is the (u, v) = (column, row) pixel
    position of the top-left corner of texture i inside `image`."""

    image: np.ndarray
    offsets: np.ndarray  # (N, 2) int64


def pack_atlas(images: list[np.ndarray], width: int = 4096) -> Atlas:
    """Shelf packing: tallest images first, left to right, a new shelf when a row is full.

    The images of a building are mostly wall panels of one height, so shelves waste little.
    """
    if not images:
        return Atlas(np.zeros((1, 1, 3), dtype=np.uint8), np.zeros((0, 2), dtype=np.int64))
    widest = max(im.shape[1] for im in images)
    width = max(width, widest)
    order = sorted(range(len(images)), key=lambda i: (-images[i].shape[0], -images[i].shape[1]))
    offsets = np.zeros((len(images), 2), dtype=np.int64)
    shelf_y, shelf_h, x = 0, 0, 0
    for i in order:
        h, w = images[i].shape[:2]
        if x + w > width:
            shelf_y, x, shelf_h = shelf_y + shelf_h, 0, 0
        if shelf_h == 0:
            shelf_h = h
        offsets[i] = (x, shelf_y)
        x += w
    total_h = shelf_y + shelf_h
    # Trim the width to what the shelves use, so a small building gets a small atlas.
    used_w = int(max(offsets[i, 0] + images[i].shape[1] for i in range(len(images))))
    atlas = np.zeros((total_h, used_w, 3), dtype=np.uint8)
    for i, im in enumerate(images):
        u, v = offsets[i]
        atlas[v : v + im.shape[0], u : u + im.shape[1]] = im
    return Atlas(atlas, offsets)
