"""Control-point motion onto a whole head, part by part.

The skin turns with the jaw about its hinge (each vertex by its jaw weight: smooth skinning along the
surface) and the tracked motion's residual after that turn is spread on top by surface-aware
interpolation (whose weights are kept non-negative: no vertex moves past its controls), so every
control point lands where the motion puts it, except where that would fold
the skin (folds are relaxed, :class:`~faceanim.geometry.relax.FoldRelaxer`) or push a lip into the
teeth (it is pushed back out). The teeth are rigid: the upper set with the skull, the lower set (and
the tongue) turned by the same jaw. Eyeballs turn about their centres with the gaze (:mod:`.gaze`). Lashes and other
lid layers ride on the skin beneath them; a separate socket (a mouth lining, an eye cap) hangs from
its rim, which rides on the opening's edge. See :mod:`faceanim.parts`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from ..geometry.mesh import Mesh
from ..geometry.project import project_points
from ..geometry.relax import FoldRelaxer
from ..geometry.topology import harmonic_fill, nearest_neighbour_on, open_edges, submesh
from ..mpeg4.fapstream import FapStream
from ..parts import FaceParts
from ..parts.jaw import unfolded_jaw_weight
from ..target import Target
from .contact import TeethContact, TeethCover
from .gaze import eye_rotations
from .jawturn import JAW_LIMITS, fitted_jaw_turns, jaw_angles
from .spreadshares import bounded_shares, scalp_hold
from .transfer import SparseTransfer

__all__ = ["PartsDeformer", "parts_frames", "deform_parts"]


class PartsDeformer:
    """Moves a target's vertices, part by part, from displacements of its control vertices.

    Parameters
    ----------
    target : Target
    parts : FaceParts
        Of the same target (:func:`faceanim.parts.face_parts`).
    control_vertices : (K,) int64
        Distinct vertex ids whose displacements will be given; those off the skin (an iris point on
        an eyeball) are ignored, since their parts move as wholes, and so are those on no skin triangle.

    Calling it with displacements ``(T, K, 3)``, jaw angles ``(T,)`` and optionally eye rotations
    ``(T, 2, 3, 3)`` gives positions ``(T, V, 3)``.
    """

    def __init__(self, target: Target, parts: FaceParts, control_vertices, *, falloff: float = 0.25,
                 relax: bool = True):
        mesh = target.mesh
        ids = np.asarray(control_vertices, dtype=np.int64)
        skin = parts.mask("skin")
        self._skin_triangles = mesh.triangles[skin[mesh.triangles].all(axis=1)]
        # A skin vertex in no skin triangle (a lip's rim the mouth's inside, cut off as a socket, borders
        # all round: ICT identity 310's mp88) has no surface to spread its motion over; as a control it
        # is left out like one off the skin (its ids made the spread's operator fail).
        spreads = np.zeros(len(mesh.vertices), dtype=bool)
        spreads[self._skin_triangles] = True
        self.in_spread = spreads[ids]
        if not self.in_spread.any():
            raise InputError("no control point lies on the skin's surface (a skin triangle); label the target's parts "
                             "with --parts PARTS.json")
        skin_ids = np.flatnonzero(skin)
        skin_mesh, index = submesh(mesh, skin)
        self.rest = mesh.vertices
        self.parts = parts
        self.skin_ids = skin_ids
        self.controls = ids
        self.spread = SparseTransfer(skin_mesh, index[ids[self.in_spread]], falloff=falloff,
                                     bounded=bounded_shares(target, skin_mesh.vertices))
        held = scalp_hold(target, skin_mesh.vertices, parts.axes[1])
        if held is not None:  # the scalp, above the face the points were placed on, held past a short fade
            self.spread.fade(held)
        r = mesh.vertices - parts.hinge
        axis = parts.axes[0]
        # turned_vectors' (R - I) r = sin(t) a x r + (1 - cos(t)) a x (a x r), its products kept per vertex
        self._turn_sin = np.cross(axis, r)
        self._turn_cos = np.cross(axis, self._turn_sin)
        # Below the lower lip's lowest point (8.2): the chin, the jaw line and the neck it swings into.
        lip = target.points.get("8.2")
        self._under_lips = (None if lip is None
                            else skin & ((mesh.vertices - mesh.vertices[lip]) @ parts.axes[1] < 0.0))
        self._mouth_width = target.mouth_width
        self._bind_riders(mesh, skin_mesh)
        self.contact = TeethContact(target, parts, skin_ids)
        self.cover = TeethCover(target, parts, skin_ids)
        self.relaxer = FoldRelaxer(skin_mesh.vertices, skin_mesh.triangles) if relax else None

    def _bind_riders(self, mesh: Mesh, skin_mesh: Mesh):
        """Lid layers ride on the skin point nearest each (skin-local corner ids, barycentric weights),
        a socket's rim on the opening's edge; deep inside, a socket is held by the gums, and between
        them and its rim it hangs (the harmonic fill of their motion over it), so the inside of the
        mouth spans the lips however far they part, with its floor going down with the lower lip."""
        socket = self.parts.mask("socket")
        rim = np.zeros(len(mesh.vertices), dtype=bool)
        socket_triangles = mesh.triangles[socket[mesh.triangles].all(axis=1)]
        if len(socket_triangles):
            rim[np.unique(open_edges(socket_triangles))] = True
        layers = np.flatnonzero(self.parts.mask("lid_layer"))
        hit = project_points(skin_mesh, mesh.vertices[layers])
        corners, bary = hit.corner_vertices, hit.barycentric
        rims = np.flatnonzero(socket & rim)
        if len(rims):
            # A separate socket's rim copies the opening's edge, set back and widened: it rides on the
            # edge vertex it copies (the nearest across the face), not on whatever skin is nearest in
            # space. A rim joined to the skin (the mouth's inside cut off from the lips, see
            # faceanim.parts.mouth) rides on the skin vertex it is joined to: across the face, the upper
            # lip's lining lies nearer the lower lip's edge than the upper's on some heads.
            edge = np.unique(open_edges(skin_mesh.triangles))
            across = self.parts.axes[:2]
            gap = ((mesh.vertices[rims] @ across.T)[:, None] - (skin_mesh.vertices[edge] @ across.T)[None]) ** 2
            nearest = edge[np.argmin(gap.sum(axis=2), axis=1)]
            joined = nearest_neighbour_on(mesh, rims, self.parts.mask("skin"))
            nearest = np.where(joined >= 0, np.searchsorted(self.skin_ids, joined), nearest)
            corners = np.vstack([corners, np.repeat(nearest[:, None], 3, axis=1)])
            bary = np.vstack([bary, np.tile([1.0, 0.0, 0.0], (len(rims), 1))])
        riders = np.r_[layers, rims]
        self._riders = (riders, corners, bary) if len(riders) else None
        # Deep inside (further than _GUM_DEPTH of the mouth's width from any socket's rim, in space; an eye
        # cap is never that wide) a socket is held by
        # the gums: it turns with the jaw by its weight (faceanim.parts: below the bite and in front of
        # the turning centre). Between the gums and the rim it hangs, each vertex the mean of its
        # neighbours. Hung from the rim alone, the upper lip's lining hung from both lips through the
        # back of the mouth: on ICT's own jawOpen it sagged 0.34 cm (median) below the truth, 0.07 held.
        hanging = np.flatnonzero(socket & ~rim)
        self._hanging = None
        if len(hanging) and rim[socket].any():
            deep = np.zeros(len(mesh.vertices), dtype=bool)
            if self._mouth_width > 0:
                apart = cKDTree(mesh.vertices[socket & rim]).query(
                    mesh.vertices[hanging], distance_upper_bound=_GUM_DEPTH * self._mouth_width)[0]
                deep[hanging[~np.isfinite(apart)]] = True
            between, held = np.flatnonzero(socket & ~rim & ~deep), np.flatnonzero((socket & rim) | deep)
            if len(between):
                fill = harmonic_fill(socket_triangles, len(mesh.vertices), between, held)
                used = np.abs(fill).max(axis=0) > 0  # most of the deep vertices border nothing that hangs
                self._hanging = between, held[used], fill[:, used]

    def jaw_turn(self, angles, vertices=None) -> np.ndarray:
        """``(T, N, 3)`` the ``vertices`` (default: all) turned fully about the hinge by ``angles (T,)``."""
        angles = np.asarray(angles, dtype=np.float64)
        at = slice(None) if vertices is None else vertices
        return (np.sin(angles)[:, None, None] * self._turn_sin[at]
                + (1 - np.cos(angles))[:, None, None] * self._turn_cos[at])

    def fitted_jaw_weight(self, displacements, angles) -> np.ndarray:
        """``(V,)`` the parts' jaw weight with the skin's share adjusted to the motion: at each control
        point on the skin, the share of the jaw's turn that best explains its displacements over all
        frames (least squares, within [0, 1]); the differences from the parts' weights spread over the
        skin like the displacements (so far from the control points the parts' weights hold).

        Without this the residual after the turn is wherever the parts' weights guessed wrong, and
        between control points the skin falls back towards the guess: a crease at every control.
        It is not raised against folding (:meth:`unfolded` gives the fold-free weight the fold fill
        falls back on)."""
        weight = self.parts.jaw_weight.copy()
        if not weight.any():  # a target with no jaw (no face points to place one): nothing to fit
            return weight
        controls = self.controls[self.in_spread]
        energy, along = np.zeros(len(controls)), np.zeros(len(controls))
        for start in range(0, len(angles), _FIT_CHUNK):  # sums over frames, a chunk of the motion at a time
            at = slice(start, start + _FIT_CHUNK)
            turn = self.jaw_turn(angles[at], controls)  # (t, K, 3)
            energy += (turn ** 2).sum(axis=(0, 2))
            along += (displacements[at][:, self.in_spread] * turn).sum(axis=(0, 2))
        seen = energy > 1e-12 * max(energy.max(), 1e-300)
        share = np.where(seen, along / np.where(seen, energy, 1.0), weight[controls])
        change = np.clip(share, 0.0, 1.0) - weight[controls]
        weight[self.skin_ids] = np.clip(weight[self.skin_ids] + self.spread.operator @ change, 0.0, 1.0)
        return weight

    def unfolded(self, weight, angles, movable=None) -> np.ndarray:
        """``weight`` raised on the skin (or on the ``movable`` vertices) where the motion's widest
        opening (or furthest closing) would fold it (:func:`~faceanim.parts.jaw.unfolded_jaw_weight`)."""
        return unfolded_jaw_weight(self.rest, self._skin_triangles, weight, self.parts.hinge, self.parts.axes[0],
                                   angles, movable=self.parts.mask("skin") if movable is None else movable)

    def __call__(self, displacements, angles, eyes=None, *, fit_weights: bool = True) -> np.ndarray:
        """Positions ``(T, V, 3)``, all at once (see :meth:`source` for a long motion)."""
        return self.source(displacements, angles, eyes, fit_weights=fit_weights)(0, len(displacements))

    def source(self, displacements, angles, eyes=None, *, fit_weights: bool = True):
        """A :data:`~faceanim.geometry.animation.FrameSource`: ``frames(start, stop)`` gives the positions
        ``(stop - start, V, 3)`` of those frames. Frames are independent once the jaw weight is fitted
        (over all frames, from the control points only), so any run of them is made on its own and
        what is held does not grow with the length of the motion beyond the control points' motion."""
        displacements = as_frames(displacements)
        angles = np.asarray(angles, dtype=np.float64)
        eyes = None if eyes is None else np.asarray(eyes, dtype=np.float64)
        weight = self.fitted_jaw_weight(displacements, angles) if fit_weights else self.parts.jaw_weight
        unfolded = self.unfolded(weight, angles)
        if self.relaxer is None or self._under_lips is None:  # turn by the fold-free weight throughout
            weight = unfolded
        else:  # raised only under the lips (see _frames)
            weight = self.unfolded(weight, angles, self._under_lips)

        def frames(start: int, stop: int) -> np.ndarray:
            at = slice(start, stop)
            return self._frames(displacements[at], angles[at], None if eyes is None else eyes[at], weight, unfolded)

        return frames

    def _frames(self, displacements, angles, eyes, weight, unfolded) -> np.ndarray:
        """The motion rides on the jaw's turn by ``weight``; where it folds, the fold fill falls back on
        the turn by ``unfolded``, which does not fold.

        ``weight`` is raised against folding only under the lips, where the chin swings into the
        neck: folds there are wide, and a fill that wide reaches the chin and takes back its drop
        (d18 onto the ICT head: the chin 0.5 cm short of its 3.4 cm at the widest frames). Beside
        the mouth the raise lowers the upper lip's corners towards the jaw, and the residual put
        back only at the control points: turned by it at every frame, the upper lip hung over the
        wide-open mouth in ragged folds between its controls (frame 83). There the fill, over the
        fully raised turn, mends only the frames and places that fold; and where the skin below the
        lips was carried behind the teeth (d6, frames 788-789: lips pursed high while the jaw drops
        25 degrees), which the fully raised turn had folded and so hid, it is put back on that turn
        (:meth:`_kept_in_front_of_teeth`)."""
        turn = self.jaw_turn(angles)  # (T, V, 3)
        moved = turn * weight[None, :, None]
        controls = self.controls[self.in_spread]
        residual = displacements[:, self.in_spread] - moved[:, controls]
        skin_field = moved[:, self.skin_ids] + self.spread(residual)
        if self.relaxer is None:
            self.contact(skin_field, angles)
        else:
            jaw_only = self.rest[self.skin_ids] + turn[:, self.skin_ids] * unfolded[self.skin_ids, None]
            relaxed, _ = self.relaxer(self.rest[self.skin_ids] + skin_field, jaw_only)
            skin_field = relaxed - self.rest[self.skin_ids]
            self._kept_in_front_of_teeth(skin_field, jaw_only, angles)
            self._kept_out_of_teeth(skin_field, jaw_only, angles)
        moved[:, self.skin_ids] = skin_field
        if self._riders is not None:
            riders, corners, bary = self._riders
            moved[:, riders] = np.einsum("nc,tncd->tnd", bary, skin_field[:, corners])
        if self._hanging is not None:  # between its rim (riding) and the gums (turned by the jaw above)
            hanging, held, fill = self._hanging
            moved[:, hanging] = np.einsum("hr,trd->thd", fill, moved[:, held])
        if eyes is not None:
            eyes = np.asarray(eyes, dtype=np.float64)
            for k, side in enumerate(("eye_left", "eye_right")):
                ball = np.flatnonzero(self.parts.mask(side))
                if len(ball):
                    r = self.rest[ball] - self.parts.eye_centres[k]
                    moved[:, ball] = np.einsum("tij,nj->tni", eyes[:, k], r) - r
        moved += self.rest
        return moved

    def _kept_in_front_of_teeth(self, skin_field, jaw_only, angles) -> None:
        """The skin in ``skin_field (T, S, 3)`` that the teeth came through (:class:`~.contact.TeethCover`)
        put back on the jaw's turn alone with the rings around it, blended into the rest and relaxed,
        in place: a frame the teeth still show through is made again from more rings
        (:data:`_COVER_RINGS`)."""
        rest = self.rest[self.skin_ids]
        hidden = self.cover(skin_field, angles)
        again = np.flatnonzero(hidden.any(axis=1))
        given = skin_field[again]
        for rings in _COVER_RINGS:
            if not len(again):
                return
            relaxed, _ = self.relaxer(rest + given, jaw_only[again], seeds=hidden[again], seed_rings=rings)
            skin_field[again] = relaxed - rest
            still = self.cover(skin_field[again], angles[again])
            hidden[again] |= still
            keep = still.any(axis=1)
            again, given = again[keep], given[keep]

    def _kept_out_of_teeth(self, skin_field, jaw_only, angles) -> None:
        """Pushes the lips in ``skin_field (T, S, 3)`` out of the teeth, in place, without folding the
        skin: a push moves lip vertices one by one and can fold the skin between them, so pushes and
        relaxations around the pushed vertices (held where the push put them) take turns."""
        rest = self.rest[self.skin_ids]
        pushed = self.contact(skin_field, angles)
        for _ in range(_CONTACT_ROUNDS):
            again = np.flatnonzero(pushed.any(axis=1))
            if not len(again):
                return
            relaxed, _ = self.relaxer(rest + skin_field[again], jaw_only[again], pushed[again])
            field = relaxed - rest
            # What the relaxation took back in (only what it moved can have gone in).
            more = self.contact(field, angles[again], among=(field != skin_field[again]).any(axis=2))
            skin_field[again] = field
            if not more.any():
                break
            pushed[again] |= more
        again = np.flatnonzero(pushed.any(axis=1))
        # Pushes that disagree (a lip caught between the upper and lower teeth at the corner is pushed
        # both ways) can hold a fold among the pushed vertices themselves. A fold is worse than a lip
        # a fraction of a millimetre into a tooth, so there the pins yield.
        relaxed, _ = self.relaxer(rest + skin_field[again], jaw_only[again], pushed[again], pins_yield=True)
        settled = relaxed - rest
        # Then a last push out of the teeth that folds nothing: each vertex alone, or where that folds
        # carried onto the skin around each pushed vertex, over wider patches in turn.
        # A push is kept if it turns no triangle the relaxation left unturned.
        was_turned = [self.relaxer.turned(rest + f) for f in settled]
        folding = np.arange(len(again))
        for radius in _EASED_RADII:
            field = settled[folding].copy()
            self.contact.eased(field, angles[again[folding]], radius * self.contact.reach)
            clear = np.array([not (self.relaxer.turned(rest + f) & ~was_turned[k]).any()
                              for f, k in zip(field, folding, strict=True)])
            skin_field[again[folding[clear]]] = field[clear]
            folding = folding[~clear]
            if not len(folding):
                return
        skin_field[again[folding]] = settled[folding]  # every push folds something: no last push


_GUM_DEPTH = 0.25  # of the mouth's width: a socket further than this from every socket rim is held by the gums
_COVER_RINGS = (2, 4, 8, 16)  # rings around skin the teeth show through that are filled, tried in turn
_CONTACT_ROUNDS = 4  # pushes out of the teeth and relaxations around them, taken in turn
# Lip reaches (0.04 of the mouth's width): how far the last push is carried, tried in turn. 4 reaches: d6
# frame 568 onto the default avatar (a smile with the mouth a little open), every narrower patch folded
# the skin and a lip stayed 0.039 cm in the upper teeth (tests/test_parts.py).
_EASED_RADII = (0.0, 0.25, 0.5, 1.0, 2.0, 4.0)
_FIT_CHUNK = 1024  # frames of the control points' motion read at once by the fits over all frames


def as_frames(displacements):
    """``(T, K, 3)`` control displacements as given: an array (converted to float64), or any object
    read by runs of frames (``len`` and ``displacements[a:b]`` giving ``(b - a, K, 3)``, as a streamed
    capture's carried controls are), so that a long motion is read a run at a time, never held."""
    if isinstance(displacements, (np.ndarray, list, tuple)):
        return np.asarray(displacements, dtype=np.float64)
    if not (hasattr(displacements, "__len__") and hasattr(displacements, "__getitem__")):
        raise TypeError(f"displacements must be an array (T, K, 3) or read by runs of frames, got "
                        f"{type(displacements).__name__}")
    return displacements


def parts_frames(target: Target, parts: FaceParts | None, control_vertices, displacements,
                 gaze: FapStream | None = None):
    """A :data:`~faceanim.geometry.animation.FrameSource` of ``target`` moved by its control vertices'
    ``displacements (T, K, 3)``, part by part: the jaw turned about the centre and by the turns the
    chin's control points say (:func:`~.jawturn.fitted_jaw_turns`; where they say nothing, about the
    parts' centre by the angle of the chin, feature point 2.1, when it is a control vertex), the
    eyeballs turned by ``gaze``'s FAPs when given. ``parts`` defaults to the target's own."""
    from ..parts import face_parts

    parts = face_parts(target) if parts is None else parts
    ids = np.asarray(control_vertices, dtype=np.int64)
    chin = np.flatnonzero(ids == target.points.get("2.1", -1))
    displacements = as_frames(displacements)
    turns = None
    if parts.jaw_weight.any():
        lip = target.points.get("8.2")
        turns = fitted_jaw_turns(parts, target.mesh.vertices, ids, displacements, mouth_width=target.fapu.mw0,
                                 below=None if lip is None else target.mesh.vertices[lip], limits=JAW_LIMITS)
    if turns is not None:
        parts = replace(parts, hinge=turns.centre)
        angles = turns.angles
    elif len(chin) and parts.jaw_weight.any():
        chin_moves = np.concatenate([displacements[a:a + _FIT_CHUNK][:, chin[0]]
                                     for a in range(0, len(displacements), _FIT_CHUNK)])
        angles = jaw_angles(parts, target.mesh.vertices[ids[chin[0]]], chin_moves)
    else:
        angles = np.zeros(len(displacements))
    deformer = PartsDeformer(target, parts, ids)
    eyes = eye_rotations(gaze, parts) if gaze is not None else None
    return deformer.source(displacements, angles, eyes)


def deform_parts(target: Target, parts: FaceParts | None, control_vertices, displacements,
                 gaze: FapStream | None = None) -> np.ndarray:
    """``(T, V, 3)`` positions, all at once, of :func:`parts_frames`."""
    return parts_frames(target, parts, control_vertices, displacements, gaze)(0, len(displacements))
