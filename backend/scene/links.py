"""Per-object ray visibility, light linking and shadow linking (Blender's Object > Visibility
and Light Linking, with Cycles' semantics): the scene fields and the tables the kernels read.

Ray types are bits (``CAMERA`` … ``SHADOW``); an object (and a lamp) carries the set of ray
types that see it. A ray of a type that does not see an object passes through it as if it were
absent (its emission too); an object invisible to shadow rays casts no shadow on anything.

Light linking follows Cycles' light sets: every emitter (lamp, emissive object) with a receiver
list lights a subset of the objects; the objects are grouped by the combination of linked
emitters that light them ("receiver sets", at most 64 as in Cycles), and each emitter gets a
64-bit mask of the receiver sets it lights (all ones: not linked). Shadow linking is the same
with blockers: each object is in a "blocker set" and a lamp's shadow mask lists the sets whose
objects cast its shadows. A list ``{"include": [...], "exclude": [...]}`` means what a Blender
collection with per-object link states means (measured with Cycles 5.0.1): with an ``include``
list (even an empty one), only the included objects; otherwise every object but the excluded
ones (an object in both lists counts as excluded).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..limits import short

CAMERA, DIFFUSE, GLOSSY, TRANSMIT, SHADOW = 1, 2, 4, 8, 16
ALL_RAYS = CAMERA | DIFFUSE | GLOSSY | TRANSMIT | SHADOW
#: A lane's receiver set when light linking does not apply to it (camera rays: Cycles shows a
#: linked emitter to the camera whatever its receivers, measured with 5.0.1).
NO_RECEIVER = 64
MAX_SETS = 64
ALL_SETS = -1                      # int64 with every bit set: an unlinked emitter

# Scene fields: (field, bit). visible_camera is read where objects and lights always read it.
OBJECT_FLAGS = (("visible_diffuse", DIFFUSE), ("visible_glossy", GLOSSY),
                ("visible_transmission", TRANSMIT), ("visible_shadow", SHADOW))
LIGHT_FLAGS = OBJECT_FLAGS[:3]     # a lamp's own shadow switch is Blender's Cast Shadow (not here)


@dataclass(frozen=True)
class LinkList:
    """An include/exclude list of object names (``path``: its field, for messages)."""
    include: tuple | None     # None: no "include" list (every object but the excluded)
    exclude: tuple
    path: str

    def members(self, names: list[str]) -> np.ndarray:
        """Which of the objects (by name) the list selects."""
        exc = set(self.exclude)
        if self.include is not None:
            inc = set(self.include)
            return np.array([n in inc and n not in exc for n in names], bool)
        return np.array([n not in exc for n in names], bool)


def parse_visibility(node, flags, bits: int = 0) -> int:
    """``bits`` plus the ray-type bits of an object's or lamp's ``visible_*`` fields (default
    true)."""
    for key, bit in flags:
        if node.boolean(key, True):
            bits |= bit
    return bits


def _parse_list(node) -> LinkList:
    node.require_object()
    lists = []
    for key in ("include", "exclude"):
        child = node.optional_child(key)
        if child is None:
            lists.append(None)
            continue
        names = []
        for item in child.items():
            if not isinstance(item.value, str):
                from .reader import _describe
                raise item.fail(f"expected an object name, got {_describe(item.value)}")
            names.append(item.value)
        lists.append(tuple(names))
    node.finish()
    return LinkList(lists[0], lists[1] or (), node.path)


def parse_linking(node, blockers: bool):
    """``light_linking`` of a lamp (receivers and blockers) or an object (receivers only: shadow
    linking of emissive objects is not rendered); (receivers, blockers), each a LinkList or None."""
    child = node.optional_child("light_linking")
    if child is None:
        return None, None
    child.require_object()
    rec = child.optional_child("receivers")
    blk = child.optional_child("blockers") if blockers else None
    child.finish()
    return (_parse_list(rec) if rec is not None else None,
            _parse_list(blk) if blk is not None else None)


@dataclass
class Links:
    """Tables for the integrator (object index = the scene's ``objects`` order; lamp index = the
    order of the scene's ``lights``)."""
    object_vis: np.ndarray       # (O,) uint8 ray-type bits
    receiver_set: np.ndarray     # (O,) uint8
    blocker_set: np.ndarray      # (O,) uint8
    object_receivers: np.ndarray  # (O,) int64: receiver sets an emissive object lights
    lamp_vis: np.ndarray         # (Lm,) uint8
    lamp_receivers: np.ndarray   # (Lm,) int64
    lamp_blockers: np.ndarray    # (Lm,) int64: blocker sets that cast the lamp's shadows

    @property
    def light_linking(self) -> bool:
        return bool((self.object_receivers != ALL_SETS).any() or (self.lamp_receivers != ALL_SETS).any())

    @property
    def shadow_linking(self) -> bool:
        return bool((self.lamp_blockers != ALL_SETS).any())


def _sets(lists: list, names: list[str], what: str, ctx):
    """(set of each object (O,) uint8, mask of each list's emitter (E,) int64) for the emitters'
    LinkLists (None: not linked)."""
    masks = np.full(len(lists), ALL_SETS, np.int64)
    linked = [i for i, l in enumerate(lists) if l is not None]
    if not linked or not names:
        return np.zeros(len(names), np.uint8), masks
    known = set(names)
    for i in linked:
        for key in ("include", "exclude"):
            for j, n in enumerate(getattr(lists[i], key) or ()):
                if n not in known:
                    raise ctx.error(f"{lists[i].path}.{key}[{j}]", f"unknown object {short(n)!r}")
    selected = np.array([lists[i].members(names) for i in linked])          # (k, O)
    signatures, object_set = np.unique(selected.T, axis=0, return_inverse=True)
    if signatures.shape[0] > MAX_SETS:
        raise ctx.error(lists[linked[0]].path, f"{what} splits the objects into {signatures.shape[0]} "
                                               f"groups; at most {MAX_SETS} are supported (as in Cycles)")
    for j, i in enumerate(linked):
        bits = sum(1 << s for s in range(signatures.shape[0]) if signatures[s, j])
        masks[i] = bits - (1 << 64) if bits >= 1 << 63 else bits
    return object_set.astype(np.uint8).ravel(), masks


def build_links(soup, lamps: list, ctx) -> Links:
    names = list(soup.object_names)
    lamp_rec = [getattr(l, "receivers", None) for l in lamps]
    lamp_blk = [getattr(l, "blockers", None) for l in lamps]
    receiver_set, masks = _sets(lamp_rec + list(soup.object_receivers), names, "light linking", ctx)
    blocker_set, blk_masks = _sets(lamp_blk, names, "shadow linking", ctx)
    lamp_vis = np.array([getattr(l, "ray_vis", ALL_RAYS) for l in lamps], np.uint8)
    return Links(np.asarray(soup.object_vis, np.uint8), receiver_set, blocker_set,
                 masks[len(lamps):], lamp_vis, masks[:len(lamps)], blk_masks)
