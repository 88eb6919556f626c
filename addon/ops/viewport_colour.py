"""Keep each layer-stack material's node tree showing an approximation of its stack, so Cycles,
EEVEE, Material Preview and Solid mode show its colour instead of a default grey (the inputs:
addon/viewport_colour.py; the albedo: the backend's ``bsdf albedo``, run in a child process).

The approximation is a Principled BSDF named "Lamina Viewport" feeding a Material Output named
"Lamina Viewport Output" that is made the active output while the stack is on; the user's own
nodes stay untouched beside it, and their output becomes active again when the stack is turned
off (Lamina itself renders the stack and never reads these two nodes). The material's viewport
display colour, metallic and roughness (Solid mode) follow too.

When: after a preset is applied or a stack operator runs, and, in the UI, whenever a stack's
fingerprint changes (a timer looks every two seconds; an edit of a slider waits until it has
settled). One child process at a time, a second or two each (measuring 20 000 sampled directions).
Under ``blender -b`` and the bpy module timers do not run: ``update_now`` does the work at once
(the showcase generator, tests). No Python thread (see engine/job.py).
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import bpy

from .. import viewport_colour as approx
from ..export import preset_link
from ..launch import python_executable
from ..presets.library import backend_environment

NODE = "Lamina Viewport"
OUTPUT = "Lamina Viewport Output"
POLL_SECONDS = 0.25
WATCH_SECONDS = 2.0

_queue: dict = {}                  # material name → (constant material JSON, fingerprint)
_running: dict = {"name": None, "proc": None, "doc": None, "stamp": None, "out": None, "err": None}
_applied: dict = {}                # material name → fingerprint its nodes show


def stack_doc(material) -> dict | None:
    """The stack's material JSON as Lamina renders it (the linked preset's own JSON while the
    stack is unchanged since it was applied), textures replaced by constants."""
    settings = material.lamina
    try:
        if preset_link.state(material) == preset_link.EXACT and settings.preset_material:
            doc = json.loads(settings.preset_material)
        else:
            text = preset_link.fingerprint(material)
            doc = json.loads(text) if text else None
    except ValueError:
        return None
    return approx.constant_doc(doc) if isinstance(doc, dict) else None


def _command(path: Path) -> list[str]:
    return [python_executable(), "-m", "backend", "bsdf", "albedo", str(path), "--theta",
            f"{approx.ALBEDO_THETA:g}", "--samples", str(approx.ALBEDO_SAMPLES), "--json"]


def request(material, force: bool = False) -> None:
    """Measure ``material``'s stack again (in the background) unless its nodes show it already.
    Only in the UI: under ``blender -b`` and the bpy module nothing would collect the result (no
    timers), and a script applying presets should not start a process per preset; scripts call
    ``update_now`` (or the operator) where they want it."""
    if bpy.app.background:
        return
    _enqueue(material, force)


def _enqueue(material, force: bool) -> None:
    if material is None or not material.lamina.use_stack:
        return
    stamp = preset_link.fingerprint(material)
    if not stamp or (not force and _applied.get(material.name) == stamp):
        return
    doc = stack_doc(material)
    if doc is None:
        return
    _queue[material.name] = (doc, stamp)
    pump()
    if not bpy.app.background and not bpy.app.timers.is_registered(_tick):
        bpy.app.timers.register(_tick, first_interval=POLL_SECONDS)


def update_now(material, timeout: float = 120.0) -> bool:
    """Measure and write ``material``'s approximation before returning (scripts, tests)."""
    _enqueue(material, True)
    deadline = time.monotonic() + timeout
    while _queue or _running["proc"] is not None:
        pump()
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return _applied.get(material.name) == preset_link.fingerprint(material)


def pump() -> None:
    proc = _running["proc"]
    if proc is not None and proc.poll() is not None:
        _collect(proc)
    if _running["proc"] is None and _queue:
        name = next(iter(_queue))
        doc, stamp = _queue.pop(name)
        _start(name, doc, stamp)


def _start(name: str, doc: dict, stamp: str) -> None:
    folder = Path(tempfile.mkdtemp(prefix="lamina-viewport-"))
    path = folder / "material.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    out = tempfile.TemporaryFile(mode="w+", encoding="utf-8", errors="replace")
    err = tempfile.TemporaryFile(mode="w+", encoding="utf-8", errors="replace")
    try:
        proc = subprocess.Popen(_command(path), env=backend_environment(), cwd=folder,
                                stdin=subprocess.DEVNULL, stdout=out, stderr=err)
    except OSError as exc:
        out.close()
        err.close()
        print(f"Lamina: cannot measure the viewport colour of '{name}': {exc}", file=sys.stderr)
        return
    _running.update(name=name, proc=proc, doc=doc, stamp=stamp, out=out, err=err)


def _collect(proc) -> None:
    name, doc, stamp, out, err = (_running[k] for k in ("name", "doc", "stamp", "out", "err"))
    _running.update(name=None, proc=None, doc=None, stamp=None, out=None, err=None)
    out.seek(0)
    err.seek(0)
    text, problem = out.read(), err.read().strip().splitlines()
    out.close()
    err.close()
    material = bpy.data.materials.get(name)
    if material is None or not material.lamina.use_stack:
        return
    try:
        albedo = json.loads(text)
    except ValueError:
        print(f"Lamina: the viewport colour of material '{name}' could not be measured: "
              f"{problem[-1] if problem else f'exit status {proc.returncode}'}", file=sys.stderr)
        _applied[name] = stamp           # not again until the stack changes
        return
    apply(material, approx.principled_inputs(doc, albedo))
    _applied[name] = stamp


def _set(node, names: tuple, value) -> None:
    for name in names:                    # socket names differ across Blender generations
        socket = node.inputs.get(name)
        if socket is not None:
            socket.default_value = value
            return


def apply(material, inputs: dict) -> None:
    """Write the approximation into ``material``'s node tree (and its Solid-mode colours)."""
    tree = material.node_tree
    if tree is None:
        return
    bsdf = tree.nodes.get(NODE)
    if bsdf is None or bsdf.bl_idname != "ShaderNodeBsdfPrincipled":
        bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
        bsdf.name = bsdf.label = NODE
        bsdf.location = (-400.0, -600.0)
    output = tree.nodes.get(OUTPUT)
    if output is None or output.bl_idname != "ShaderNodeOutputMaterial":
        output = tree.nodes.new("ShaderNodeOutputMaterial")
        output.name = output.label = OUTPUT
        output.location = (-100.0, -600.0)
    output.target = "ALL"
    if not any(link.from_node == bsdf for link in output.inputs["Surface"].links):
        tree.links.new(bsdf.outputs["BSDF"], output.inputs["Surface"])
    colour = tuple(float(c) for c in inputs["base_color"])
    _set(bsdf, ("Base Color",), (*colour, 1.0))
    _set(bsdf, ("Metallic",), float(inputs["metallic"]))
    _set(bsdf, ("Roughness",), float(inputs["roughness"]))
    _set(bsdf, ("Transmission Weight", "Transmission"), float(inputs["transmission"]))
    _activate(tree, output)
    material.diffuse_color = (*colour, 1.0)
    material.metallic = float(inputs["metallic"])
    material.roughness = float(inputs["roughness"])


def _activate(tree, output) -> None:
    for node in tree.nodes:
        if node.bl_idname == "ShaderNodeOutputMaterial" and node is not output:
            node.is_active_output = False
    output.is_active_output = True


def release(material) -> None:
    """The stack is off: the user's own output is the active one again."""
    tree = material.node_tree
    ours = tree.nodes.get(OUTPUT) if tree is not None else None
    if ours is None:
        return
    others = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial" and n is not ours]
    ours.is_active_output = False
    if others:
        others[0].is_active_output = True
    _applied.pop(material.name, None)


def _tick():
    pump()
    return POLL_SECONDS if (_queue or _running["proc"] is not None) else None


def _watch():
    """Every two seconds (UI only): stacks whose fingerprint changed are measured again."""
    try:
        for material in bpy.data.materials:
            if material.lamina.use_stack:
                if material.library is None:
                    request(material)
            elif material.name in _applied:
                release(material)
    except (AttributeError, ReferenceError):
        pass
    return WATCH_SECONDS


class LAMINA_OT_viewport_colour(bpy.types.Operator):
    bl_idname = "lamina.viewport_colour"
    bl_label = "Update Viewport Colour"
    bl_description = ("Measure the layer stack's colour and show it in Cycles, EEVEE and Solid mode "
                      "through a Principled BSDF (an approximation; Lamina renders the stack itself)")

    @classmethod
    def poll(cls, context):
        material = getattr(context, "material", None)
        return material is not None and material.lamina.use_stack

    def execute(self, context):
        if bpy.app.background:
            if not update_now(context.material):
                self.report({"WARNING"}, "Lamina: the viewport colour could not be measured (see the console)")
        else:
            request(context.material, force=True)
        return {"FINISHED"}


def register():
    bpy.utils.register_class(LAMINA_OT_viewport_colour)
    if not bpy.app.background:
        bpy.app.timers.register(_watch, first_interval=WATCH_SECONDS, persistent=True)


def unregister():
    for timer in (_watch, _tick):
        if bpy.app.timers.is_registered(timer):
            bpy.app.timers.unregister(timer)
    proc = _running["proc"]
    if proc is not None:
        proc.kill()
        proc.wait()
        _running.update(name=None, proc=None)
    _queue.clear()
    bpy.utils.unregister_class(LAMINA_OT_viewport_colour)
