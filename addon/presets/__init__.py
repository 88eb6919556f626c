"""The material preset library on the Blender side.

``library``: where presets live (the shipped ``presets/`` folder and the user's folder under
``bpy.utils.extension_path_user``) and reading them, through the bpy-free ``backend/presets.py``
(imported as a sibling package, never through ``sys.path``). ``convert``: preset material JSON →
the layer-stack properties, reporting every field the editor cannot represent. ``previews``:
thumbnails as icons. The operators and menus are in ``ops/presets.py``; the link that makes
export write an unedited preset exactly is in ``export/preset_link.py``.
"""
