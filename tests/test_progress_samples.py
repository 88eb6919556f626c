"""Progress events count samples within a round (a small image renders all its samples in one
round of several work items): the status bar must not sit at 0 and end below the total."""
import copy

from backend.render import Renderer, RenderOptions
from backend.scene.loader import load_scene_data
from render_util import look_down_ortho, scene


def test_progress_counts_samples_within_a_round():
    data = scene(8, 8, look_down_ortho(1.0), {"grey": {"type": "diffuse", "color": 0.5}},
                 {"floor": {"shape": "rectangle", "size": [2.0, 2.0]}},
                 [{"mesh": "floor", "materials": ["grey"]}], world={"type": "constant", "color": [1, 1, 1]},
                 render={"spp": 64, "max_bounces": 0, "seed": 1})
    events = []
    sc = load_scene_data(copy.deepcopy(data), "<test>")
    Renderer(sc, (copy.deepcopy(data), "<test>", None), RenderOptions(workers=1), events.append).run()
    progress = [e for e in events if e.get("event") == "progress"]
    samples = [e["samples"] for e in progress]
    assert len(progress) >= 4 and all(e["total"] == 64 for e in progress)
    assert progress[0]["done"] == 0 and 0 < samples[0] < 64          # one round: "done" stays 0 ...
    assert all(b >= a for a, b in zip(samples, samples[1:]))          # ... while "samples" advances
    assert progress[-1]["done"] == 64 and samples[-1] == 64 and progress[-1]["eta"] == 0
