"""The interactive renderer session: ``python -m backend session`` (docs/session.md).

A long-lived process that holds one scene and renders it progressively while a client (the
Blender viewport, or any program) sends edits. JSON lines on stdin are commands, JSON lines on
stdout are events, and images travel through frame files (``frames.py``). Every scene state has an
*edit generation* chosen by the client; every frame carries the generation it was rendered from,
so a client never shows a frame older than its last edit.

* ``protocol.py`` — commands and events, the stdin reader (a thread, so the render loop can poll
  for commands between work items and block while idle);
* ``state.py`` — the scene document and its parsed sections; an edit re-parses and rebuilds only
  what it touches (camera → camera vector; materials → material/light tables; objects → triangle
  soup and BVH ...), with the scene loader's own parsers;
* ``loop.py`` — progressive rendering: low-resolution passes first, then full-resolution samples
  accumulated in a film up to the sample target, then idle;
* ``frames.py`` — the frame file format (header + float32 RGBA), written atomically.

Rendering goes through the same ``PathTracer`` and ``FilmAccumulator`` as ``render``.
"""
