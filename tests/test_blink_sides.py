"""Which eye a blink score is: the Face Landmarker's ``eyeBlinkLeft`` is the face's own left eye, the
one the capture's blink slide reads it for (``EYE_CORNERS["Left"]``, MediaPipe's 263 and 362).

ICT-FaceKit's ``eyeBlink_L`` shuts the eye on the face's +x side (its left); rendered from the front,
that eye is on the image's right. A mix-up would take the slide out of the open eye and leave it in
the shut one, silently: nothing else notices."""

import numpy as np
import pytest
from conftest import shared

from faceanim.capture.blinkslide import EYE_CORNERS
from faceanim.capture.scores import BLINKS
from faceanim.capture.tracker import FaceTracker, TrackerOptions

# MediaPipe's middle upper and lower lid points of each eye (the face's left, then its right).
MIDDLE_LIDS = ((386, 374), (159, 145))


@pytest.fixture(scope="module")
def one_eye_shut():
    """For ICT's eyeBlink_L and eyeBlink_R: the rendered face's landmarks and blendshape scores, and on
    which side (+x: the face's left) ICT's expression moves the skin."""
    shared("ict_facekit")
    from ict_scenario import FACE_VERTICES, load_ict
    from roundtrip_ict import ICT, source_style

    from faceanim.geometry import read_mesh
    from faceanim.render.camera import front_camera
    from faceanim.render.rasterizer import Renderer

    model = load_ict()
    names = list(model.expression_names)
    labelled = read_mesh(ICT / "obj" / "generic_neutral_mesh.obj")
    face = labelled.with_vertices(model.neutral)
    camera = front_camera(model.neutral[:FACE_VERTICES], 512, 512, vertical_fov=20.0, margin=1.1)
    seen = {}
    with Renderer(512, 512) as renderer, FaceTracker(TrackerOptions(static=True)) as tracker:
        for name in ("eyeBlink_L", "eyeBlink_R"):
            delta = model.expression_deltas[names.index(name)]
            side = np.sign(model.neutral[np.linalg.norm(delta, axis=1) > 0.1, 0].mean())
            image = renderer.render(face, camera, positions=model.neutral + delta,
                                    **source_style(model, model.neutral, labelled, "portrait"))
            landmarks = tracker(image)
            assert landmarks is not None
            seen[name] = side, landmarks, tracker.blendshapes.copy(), list(tracker.blendshape_names)
    return seen


def test_the_shut_eye_is_the_one_its_score_and_the_slide_name(one_eye_shut):
    for name, (side, landmarks, scores, names) in one_eye_shut.items():
        raw = {blink.removeprefix("eyeBlink"): scores[names.index(blink)] for blink in BLINKS}
        scored = max(raw, key=raw.get)
        assert raw[scored] > raw["Left" if scored == "Right" else "Right"] + 0.2
        # The eye the slide reads that score for is the one whose lids came together...
        gaps = {eye: abs(landmarks[top, 1] - landmarks[bottom, 1])
                for eye, (top, bottom) in zip(("Left", "Right"), MIDDLE_LIDS, strict=True)}
        assert min(gaps, key=gaps.get) == scored
        corners = landmarks[list(EYE_CORNERS[scored]), :2].mean(axis=0)
        lids = landmarks[list(MIDDLE_LIDS[0 if scored == "Left" else 1]), :2].mean(axis=0)
        assert np.linalg.norm(corners - lids) < 0.05  # the same eye (a tenth of the image apart at most)
        # ...and is on the side ICT shut: the face's left is on the image's right, seen from the front.
        assert (corners[0] > 0.5) == (side > 0) == (name == "eyeBlink_L") == (scored == "Left")
