"""Object ray visibility and light / shadow linking → scene-file fields (docs/scene-format.md).

Blender keeps light linking on the emitter (``object.light_linking.receiver_collection`` /
``blocker_collection``) with a link state per object or child collection in that collection;
the scene file lists object names under ``include`` / ``exclude`` and the backend applies
Cycles' rules (backend/scene/links.py). Names are resolved once every instance is exported, so
that only objects the file holds are named.
"""
from __future__ import annotations

# Object > Visibility > Ray Visibility switches the scene file carries (camera is written
# where it always was). Lamps take the first three; a lamp's shadow is Cast Shadow.
OBJECT_RAYS = ("visible_diffuse", "visible_glossy", "visible_transmission", "visible_shadow")
LIGHT_RAYS = OBJECT_RAYS[:3]


def visibility_fields(obj, props=OBJECT_RAYS) -> dict:
    """``{"visible_diffuse": False, ...}`` for the switches that are off (defaults are on)."""
    original = obj.original if getattr(obj, "original", None) is not None else obj
    return {p: False for p in props if not getattr(original, p, True)}


def _states(collection) -> list[tuple[str, str]]:
    """(object name, 'INCLUDE' or 'EXCLUDE') for the objects of a linking collection; a child
    collection's state applies to every object inside it."""
    # collection_objects / collection_children hold only the link states, in the order of
    # collection.objects / collection.children (bpy 5.0.1: they have no object attribute).
    out = []
    for obj, item in zip(collection.objects, getattr(collection, "collection_objects", ())):
        out.append((obj.name, item.light_linking.link_state))
    for child, item in zip(collection.children, getattr(collection, "collection_children", ())):
        state = item.light_linking.link_state
        out.extend((o.name, state) for o in child.all_objects)
    return out


def linking_source(obj, blockers: bool):
    """The collections to resolve later: {"receivers": collection, "blockers": collection}."""
    original = obj.original if getattr(obj, "original", None) is not None else obj
    linking = getattr(original, "light_linking", None)
    if linking is None:
        return {}
    found = {}
    if getattr(linking, "receiver_collection", None) is not None:
        found["receivers"] = linking.receiver_collection
    if blockers and getattr(linking, "blocker_collection", None) is not None:
        found["blockers"] = linking.blocker_collection
    return found


def resolve(source: dict, exported: set[str]) -> dict:
    """The ``light_linking`` field from ``linking_source``'s collections: names of exported
    objects only (a collection may hold lights, cameras or hidden objects)."""
    field = {}
    for role, collection in source.items():
        states = _states(collection)
        lists = {}
        if any(state == "INCLUDE" for _, state in states):
            # Present even if empty: "only these" (the included objects may all be unexported).
            lists["include"] = [n for n, state in states if state == "INCLUDE" and n in exported]
        excluded = [n for n, state in states if state != "INCLUDE" and n in exported]
        if excluded:
            lists["exclude"] = excluded
        field[role] = lists
    return field
