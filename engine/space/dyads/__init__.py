"""Closed-form configuration spaces of planar dyad chains, vectorised over the driving angle.

A planar one-degree-of-freedom linkage whose free vertices are placed one by one from a rotor's
tip, each from two placed neighbours (a *dyad*: circle-circle intersection, see
:func:`engine.space.assembly.dyad_plan`), has every configuration on a *sheet*: a choice of root
``s_j = +-1`` for each of its ``k`` dyads, over the rotor angle ``theta``. Dyad ``j`` at
``theta`` on sheet ``s`` has its vertex where ``nu_j = sin^2`` of the angle between its two bars
is positive (``nu_j`` depends on ``s_1 .. s_{j-1}`` only); where ``nu_j`` crosses zero the rotor
reaches a limit (a *fold*) and the sheets ``s`` and ``s`` with ``s_j`` flipped join. Sheets cut
at folds are *arcs*; joined end to end at their folds they are the components.

**Certificate of no critical point.** At a configuration where no dyad is collinear
(``nu_j != 0``) ``J`` has full rank (block triangular with invertible 2 x 2 blocks and the rotor
row). Where exactly one dyad is collinear, the dyad's self-stress is balanced by the rest only if
its generalised force on ``theta`` vanishes, i.e. ``d nu_j / d theta = 0``. So a linkage whose
every zero of every ``nu_j`` along every sheet is simple and away from the zeros of the other
dyads, and whose dyad centres never coincide, has no critical point at all. This module proves
that on a dense angle grid (sign changes bracketed and bisected; every discrete extremum of every
``nu_j`` refined on its bracket; every fold checked for transversality and for the other dyads'
margin, also densely inside its grid cell) and returns ``None`` whenever any check is within the
margin ``tau``: near or at critical lengths the general tracer answers instead
(:func:`engine.space.configuration_space.explore`). Never a confident wrong answer.

The margin ``tau`` (on ``nu = sin^2``) is ``1e4 * residual_atol / median bar length`` (clipped
to ``[1e-10, 1e-3]``): lengths that close to a critical value are left to the general engine,
which decides within ``residual_atol`` whether they are critical.

Modules: :mod:`.chain` (the chain of a linkage, placement on every sheet, the detection grid
and its folds), :mod:`.closed_form` (:func:`closed_form_space`), :mod:`.candidates`
(:func:`critical_candidates`).
"""

from engine.space.dyads.candidates import MAX_CANDIDATES, CriticalCandidates, critical_candidates
from engine.space.dyads.chain import DETECT_SAMPLES, MAX_DYADS, Chain, chain_of, place
from engine.space.dyads.closed_form import ClosedForm, closed_form_space

__all__ = [
    "DETECT_SAMPLES",
    "MAX_CANDIDATES",
    "MAX_DYADS",
    "Chain",
    "ClosedForm",
    "CriticalCandidates",
    "chain_of",
    "closed_form_space",
    "critical_candidates",
    "place",
]
