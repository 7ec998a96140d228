"""Module decisions and multiple-fault diagnosis (thesis eq. 5.19-5.22, section 6.4).

* :func:`latch_decisions`: D(l,q)(t) latched from the first violation of the module's ARR (eq. 5.19),
  first detection times T_D(l,q).
* :func:`minimal_diagnoses`: consistency-based diagnosis.  Every fired module's ARR has a *fault
  support* (its FSM row, the faults that may violate it); a diagnosis is a set of faults that
  hits every fired module's support, and the minimal diagnoses are the minimal hitting sets.
  Optional exoneration: a module that has not fired clears the faults that would surely have
  fired it (a matrix of such "certain" cells; by default none, i.e. no exoneration).  Optional
  temporal reasoning (``detection_times``): a fault can only explain a module if it was not
  exonerated when that module fired (faults are permanent, so the fault that fired a module
  early must have been consistent then).
* :func:`minimal_hitting_sets`: Berge's incremental algorithm on bitmasks, truncated at
  ``max_cardinality``.  Truncation is exact for the sets up to that size (every minimal
  transversal of the first i+1 conflicts of size <= k extends one of the first i of size <= k),
  and the number of candidates is at most C(26, k), so the cost is polynomial for bounded k
  (O(m C(n, k) n) for m conflicts) instead of the 2^n of enumerating all fault combinations.
  :func:`brute_force_minimal_hitting_sets` is that enumeration (the thesis's approach), kept to
  show identical results in the tests.
* :func:`thesis_global_diagnosis`: the thesis's local/global logic (eq. 5.20-5.22): local diagnosis
  sets by pattern matching against the three-valued agent tables, propagation decisions D_chi,
  the global matrix F^chi and the intersection D_s^G = D_s^chi ∩ D_s.
* :class:`DiagnosisState`: per-sample update with the module decisions; recomputes the minimal
  diagnoses only when the set of fired modules changes (at most 19 times per run).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations
from typing import Iterable, Sequence

import numpy as np

from ..engine.faults import FAULT_IDS, fault_class
from .modules import AGENTS, MODULE_IDS
from .structure import STAR, fault_agent, fault_signature_matrix, thesis_signature_matrix

__all__ = [
    "LatchedDecisions",
    "latch_decisions",
    "minimal_hitting_sets",
    "brute_force_minimal_hitting_sets",
    "fired_vector",
    "exonerated_faults",
    "diagnosis_conflicts",
    "default_settle_times",
    "minimal_diagnoses",
    "brute_force_diagnoses",
    "candidates",
    "declared_faults",
    "candidate_classes",
    "sorted_diagnoses",
    "ThesisGlobalDiagnosis",
    "thesis_global_diagnosis",
    "DiagnosisState",
    "DiagnosisEvent",
    "diagnose_decisions",
    "ThesisExample",
    "THESIS_EXAMPLES",
    "set_from_mask",
    "mhs_masks",
    "diagnosis_sort_key",
]

N_MODULES = len(MODULE_IDS)
N_FAULTS = len(FAULT_IDS)
_FAULT_INDEX = {f: i for i, f in enumerate(FAULT_IDS)}
_MODULE_INDEX = {m: i for i, m in enumerate(MODULE_IDS)}


# ----------------------------------------------------------------------------- eq. 5.19
@dataclass(frozen=True)
class LatchedDecisions:
    """decisions: bool (..., T, 19), D(l,q)(t) = 1 from the first violation on (eq. 5.19).
    first_index: int (..., 19), sample of the first violation, -1 if never.
    first_time: float (..., 19), its time T_D(l,q) (NaN if never; sample index if no times given).
    """

    decisions: np.ndarray
    first_index: np.ndarray
    first_time: np.ndarray


def latch_decisions(violations, times=None) -> LatchedDecisions:
    """Latch ARR violations (bool array (..., T, 19), True where the residual leaves its threshold)
    into module decisions (eq. 5.19) and first detection times.  ``times`` (T,) in seconds."""
    v = np.asarray(violations)
    if v.dtype != bool:
        if not np.isin(v, (0, 1)).all():
            raise ValueError("violations must be boolean (or 0/1)")
        v = v.astype(bool)
    if v.ndim < 2 or v.shape[-1] != N_MODULES:
        raise ValueError(f"violations must have shape (..., T, {N_MODULES}), got {v.shape}")
    T = v.shape[-2]
    if T == 0:
        shape = v.shape[:-2] + (N_MODULES,)
        return LatchedDecisions(v.copy(), np.full(shape, -1), np.full(shape, np.nan))
    dec = np.logical_or.accumulate(v, axis=-2)
    any_v = v.any(axis=-2)
    first = np.where(any_v, np.argmax(v, axis=-2), -1)
    if times is None:
        t = np.arange(T, dtype=float)
    else:
        t = np.asarray(times, dtype=float)
        if t.shape != (T,):
            raise ValueError(f"times must have shape ({T},), got {t.shape}")
    first_time = np.where(any_v, t[np.clip(first, 0, T - 1)], np.nan)
    return LatchedDecisions(dec, first, first_time)


# ----------------------------------------------------------------------------- minimal hitting sets
def _bits(mask: int):
    while mask:
        low = mask & -mask
        yield low
        mask ^= low


def mhs_masks(conflicts: Sequence[int], k: int) -> list[int]:
    """Berge's algorithm on bitmasks, truncated at cardinality k (exact up to k)."""
    if k < 0:
        return []
    uniq = sorted(set(conflicts), key=lambda c: (c.bit_count(), c))
    if not uniq:
        return [0]
    if uniq[0] == 0:
        return []  # a conflict no admissible fault explains
    # drop conflicts that contain another conflict: hitting the smaller one hits them
    reduced: list[int] = []
    for c in uniq:
        if not any((d & c) == d for d in reduced):
            reduced.append(c)
    hs = [0]
    for c in reduced:
        keep = [h for h in hs if h & c]
        by_bit: dict[int, list[int]] = {}
        for g in keep:
            for b in _bits(g & c):
                by_bit.setdefault(b, []).append(g)
        new = []
        for h in hs:
            if h & c or h.bit_count() >= k:
                continue
            for b in _bits(c):
                cand = h | b
                # cand is minimal unless a kept set (which must contain b) is inside it
                if not any((g & cand) == g for g in by_bit.get(b, ())):
                    new.append(cand)
        hs = keep + new
        if not hs:
            return []
    return hs


def _to_masks(conflicts: Iterable[Iterable], index: dict) -> list[int]:
    out = []
    for c in conflicts:
        m = 0
        for x in c:
            m |= 1 << index[x]
        out.append(m)
    return out


def set_from_mask(mask: int, items: Sequence) -> frozenset:
    """The items whose bits are set in ``mask`` (bit i: ``items[i]``)."""
    return frozenset(items[i] for i in range(len(items)) if mask >> i & 1)


def _items_of(conflicts: list) -> list:
    seen: dict = {}
    for c in conflicts:
        for x in c:
            seen.setdefault(x, None)
    try:
        return sorted(seen)
    except TypeError:
        return list(seen)


def minimal_hitting_sets(conflicts: Iterable[Iterable], max_cardinality: int | None = 3) -> list[frozenset]:
    """All minimal hitting sets of size <= ``max_cardinality`` (None: no bound) of a family of
    sets (conflicts).  An empty family gives ``[frozenset()]``; a family with an empty set gives
    ``[]`` (nothing can hit it).  Berge's incremental algorithm, see the module docstring."""
    conflicts = [list(c) for c in conflicts]
    items = _items_of(conflicts)
    k = len(items) if max_cardinality is None else int(max_cardinality)
    masks = mhs_masks(_to_masks(conflicts, {x: i for i, x in enumerate(items)}), k)
    return [set_from_mask(m, items) for m in masks]


def brute_force_minimal_hitting_sets(
    conflicts: Iterable[Iterable], max_cardinality: int | None = 3, universe: Iterable | None = None
) -> list[frozenset]:
    """The same by enumerating every combination of elements up to ``max_cardinality`` (the
    thesis's 2^n approach): keep those that hit every conflict and from which no element can be
    removed (hitting is monotone, so that is subset-minimality)."""
    conflicts = [frozenset(c) for c in conflicts]
    items = list(universe) if universe is not None else _items_of([list(c) for c in conflicts])
    k = len(items) if max_cardinality is None else int(max_cardinality)
    out = []
    for r in range(0, k + 1):
        for combo in combinations(items, r):
            s = frozenset(combo)
            if all(s & c for c in conflicts) and all(not all((s - {x}) & c for c in conflicts) for x in s):
                out.append(s)
    return out


# ----------------------------------------------------------------------------- diagnoses
def fired_vector(fired) -> np.ndarray:
    """Bool (19,) from a bool/0-1 vector in ``MODULE_IDS`` order or an iterable of module ids."""
    if isinstance(fired, np.ndarray) or (isinstance(fired, (list, tuple)) and fired and not isinstance(fired[0], str)):
        v = np.asarray(fired)
        if v.shape != (N_MODULES,):
            raise ValueError(f"a decision vector must have shape ({N_MODULES},), got {v.shape}")
        return v.astype(bool)
    out = np.zeros(N_MODULES, dtype=bool)
    for m in fired:
        if m not in _MODULE_INDEX:
            raise ValueError(f"unknown module {m!r}; allowed: {', '.join(MODULE_IDS)}")
        out[_MODULE_INDEX[m]] = True
    return out


def _matrix(mat, name: str) -> np.ndarray:
    a = np.asarray(mat)
    if a.shape != (N_MODULES, N_FAULTS):
        raise ValueError(f"{name} must have shape ({N_MODULES}, {N_FAULTS}), got {a.shape}")
    return a.astype(bool)


def _support(support) -> np.ndarray:
    if support is None:
        return fault_signature_matrix()[0]
    return _matrix(support, "support")


def _exoneration(exoneration, support: np.ndarray) -> np.ndarray | None:
    if exoneration is None or exoneration is False:
        return None
    if exoneration is True:
        return support
    return _matrix(exoneration, "exoneration")


def exonerated_faults(fired, exoneration) -> np.ndarray:
    """Bool (26,): faults cleared by the modules that have not fired (exoneration[m, f] for some
    non-fired m)."""
    f = fired_vector(fired)
    ex = _matrix(exoneration, "exoneration")
    return ex[~f].any(axis=0)


def diagnosis_conflicts(
    fired, *, support=None, exoneration=None, detection_times=None, settle_s=0.0, now: float | None = None, grace_s=0.0
) -> list[int]:
    """Bitmask (over ``FAULT_IDS``) of the admissible faults that can explain each fired module.

    Static (``now`` None): support row minus the faults exonerated now.  With ``detection_times``
    (19,) (NaN or inf = not fired) and an exoneration matrix: a fault can explain module m only if
    every module that would surely have fired for it had fired by T_D(m) + ``settle_s`` (a number,
    or one per fault in ``FAULT_IDS`` order, see :func:`default_settle_times`).

    With ``now`` (the current time) and ``grace_s`` (a number, one per fault (26,) or one per cell
    (19, 26)): a silent sure module m exonerates fault f only once f's first fired module is older
    than grace[m, f] (m may still fire), and only the sure modules that have fired constrain the
    time order.
    """
    f = fired_vector(fired)
    sup = _support(support)
    ex = _exoneration(exoneration, sup)
    settle = (
        np.broadcast_to(np.asarray(settle_s, dtype=float), (N_FAULTS,))
        if np.ndim(settle_s) == 0
        else np.asarray(settle_s, dtype=float)
    )
    if settle.shape != (N_FAULTS,):
        raise ValueError(f"settle_s must be a number or have shape ({N_FAULTS},), got {settle.shape}")
    td = None
    if detection_times is not None:
        td = np.asarray(detection_times, dtype=float)
        if td.shape != (N_MODULES,):
            raise ValueError(f"detection_times must have shape ({N_MODULES},), got {td.shape}")
        td = np.where(f & np.isfinite(td), td, np.inf)
    if ex is None:
        admissible_now = np.ones(N_FAULTS, dtype=bool)
    elif now is not None and td is not None:
        # first firing among each fault's support modules; inside the grace period silent sure
        # modules do not exonerate yet
        grace = np.broadcast_to(np.asarray(grace_s, dtype=float), (N_MODULES, N_FAULTS))
        first = np.where(sup & f[:, None], td[:, None], np.inf).min(axis=0)
        expired = (now - first)[None, :] > grace  # (19, 26): silent sure module no longer awaited
        admissible_now = ~(ex & expired & ~f[:, None]).any(axis=0)
    else:
        admissible_now = ~ex[~f].any(axis=0)
    if ex is not None and td is not None:
        # time from which each fault is admissible: last firing among its certain modules
        fired_or_pending = td if now is None else np.where(f, td, -np.inf)
        need = np.where(ex, fired_or_pending[:, None], -np.inf)
        admissible_from = need.max(axis=0) if N_MODULES else np.full(N_FAULTS, -np.inf)
    else:
        admissible_from = None
    conflicts = []
    for i in np.flatnonzero(f):
        ok = sup[i] & admissible_now
        if admissible_from is not None:
            t_i = td[i]
            if np.isfinite(t_i):
                ok = ok & (admissible_from <= t_i + settle)
        m = 0
        for j in np.flatnonzero(ok):
            m |= 1 << int(j)
        conflicts.append(m)
    return conflicts


def default_settle_times(sensor_s: float = 5.0, process_s: float = math.inf) -> np.ndarray:
    """Per-fault settle times for the temporal mode, (26,) in ``FAULT_IDS`` order: an abrupt sensor
    fault fires its certain modules within ``sensor_s`` of each other; an incipient process fault
    may take arbitrarily long (``inf``: a process fault is only exonerated by the current
    decisions, never by the order of detections)."""
    return np.array([sensor_s if fault_class(f) == "sensor" else process_s for f in FAULT_IDS])


def diagnosis_sort_key(s: frozenset) -> tuple:
    """Order of diagnoses: by size, then by the fault ids' order in the registry."""
    return (len(s), sorted(_FAULT_INDEX[x] for x in s))


def sorted_diagnoses(diagnoses: Iterable[Iterable[str]]) -> list[list[str]]:
    """Diagnoses as sorted lists (faults in ``FAULT_IDS`` order), smallest first (for JSON)."""
    ds = sorted((frozenset(d) for d in diagnoses), key=diagnosis_sort_key)
    return [sorted(d, key=_FAULT_INDEX.__getitem__) for d in ds]


def minimal_diagnoses(
    fired,
    *,
    support=None,
    exoneration=None,
    detection_times=None,
    settle_s=0.0,
    max_cardinality: int | None = 3,
    method: str = "berge",
    now: float | None = None,
    grace_s=0.0,
) -> list[frozenset[str]]:
    """Minimal diagnoses (sets of fault ids, smallest first) consistent with the fired modules.

    fired : bool (19,) decisions in ``MODULE_IDS`` order, or an iterable of module ids.
    support : bool (19, 26) fault supports of the ARRs (default: the derived FSM).
    exoneration : None (default, no exoneration), True (a non-fired module clears every fault of
        its support: "every structural sensitivity fires"), or a bool (19, 26) matrix of the cells
        that surely fire (e.g. ``thesis_signature_matrix() == 1``).
    detection_times, settle_s : temporal admissibility (see :func:`diagnosis_conflicts`).
    max_cardinality : largest diagnosis considered (None: no bound).
    method : 'berge' (default) or 'brute' (enumeration of all combinations up to the bound).

    No fired module gives ``[frozenset()]`` (the fault-free diagnosis); fired modules that no
    admissible fault explains give ``[]``.
    """
    conflicts = diagnosis_conflicts(
        fired,
        support=support,
        exoneration=exoneration,
        detection_times=detection_times,
        settle_s=settle_s,
        now=now,
        grace_s=grace_s,
    )
    k = N_FAULTS if max_cardinality is None else int(max_cardinality)
    if method == "berge":
        masks = mhs_masks(conflicts, k)
        out = [set_from_mask(m, FAULT_IDS) for m in masks]
    elif method == "brute":
        sets = [set_from_mask(c, FAULT_IDS) for c in conflicts]
        out = brute_force_minimal_hitting_sets(sets, k, universe=FAULT_IDS)
    else:
        raise ValueError(f"method must be 'berge' or 'brute', got {method!r}")
    return sorted(out, key=diagnosis_sort_key)


def _row_masks(mat: np.ndarray) -> list[int]:
    """Per column (fault), the bitmask of the rows (modules) where ``mat`` is nonzero."""
    out = []
    for j in range(mat.shape[1]):
        m = 0
        for i in np.flatnonzero(mat[:, j]):
            m |= 1 << int(i)
        out.append(m)
    return out


def brute_force_diagnoses(fired, *, support=None, exoneration=None, max_cardinality: int = 3) -> list[frozenset[str]]:
    """The thesis's way: enumerate every fault combination up to ``max_cardinality`` and keep the
    consistent ones (each fired module sensitive to a member; with exoneration, no member surely
    firing a silent module), then the subset-minimal ones.  Independent of the hitting-set code."""
    f = fired_vector(fired)
    sup = _support(support)
    ex = _exoneration(exoneration, sup)
    fired_mask = _row_masks(f[:, None])[0]
    cols = _row_masks(sup)
    certain = _row_masks(ex) if ex is not None else [0] * N_FAULTS
    consistent = []
    for r in range(0, max_cardinality + 1):
        for combo in combinations(range(N_FAULTS), r):
            cover = 0
            sure = 0
            for j in combo:
                cover |= cols[j]
                sure |= certain[j]
            if (cover & fired_mask) == fired_mask and not (sure & ~fired_mask):
                consistent.append(frozenset(FAULT_IDS[j] for j in combo))
    minimal = [s for s in consistent if not any(o < s for o in consistent)]
    return sorted(minimal, key=diagnosis_sort_key)


def candidates(diagnoses: Iterable[Iterable[str]]) -> tuple[str, ...]:
    """Faults appearing in at least one diagnosis, in ``FAULT_IDS`` order."""
    u = set().union(*[set(d) for d in diagnoses]) if diagnoses else set()
    return tuple(f for f in FAULT_IDS if f in u)


def declared_faults(diagnoses: Iterable[Iterable[str]]) -> list[str]:
    """The faults a diagnoser declares from its minimal diagnoses (the rule of the ``reference``
    and ``sequential`` agents): among the diagnoses of smallest cardinality (one fault is likelier
    than two at once), those in more than half of them (a tie is not a declaration); ``FAULT_IDS``
    order.  No diagnosis, or none in a majority: nothing declared (the agent then says
    ``unknown`` if anything was detected)."""
    ds = [frozenset(d) for d in diagnoses]
    if not ds:
        return []
    k = min(len(d) for d in ds)
    ds = [d for d in ds if len(d) == k]
    return [f for f in FAULT_IDS if 2 * sum(f in d for d in ds) > len(ds)]


def candidate_classes(diagnoses: Iterable[Iterable[str]]) -> dict[str, str]:
    """{fault id: 'sensor' | 'process'} for every candidate."""
    return {f: fault_class(f) for f in candidates(list(diagnoses))}


# ----------------------------------------------------------------------------- thesis logic (eq. 5.20-5.22)
@dataclass(frozen=True)
class ThesisGlobalDiagnosis:
    """Result of :func:`thesis_global_diagnosis`.

    local : {agent: consistent fault combinations D_s^(l) (frozensets of the agent's columns)};
        empty when D^(l) = 0.
    d_chi : int (4,) propagation decisions D_chi (eq. 5.20).
    chi : combinations consistent with D_chi against F^chi (D_s^chi).
    intersection : D_s^chi ∩ D_s as sets of combinations (eq. 5.21-5.22, literally; it loses
        cross-agent combinations such as {f_2^(2), f_x,int} of 6.4.3, which D_s, a union of
        single-agent sets, cannot hold).
    global_candidates : faults that occur both in some element of D_s^chi and in some element of
        D_s, the fault-level intersection the thesis's examples report as D_s^G.
    diagnoses : all combinations (all faults, size <= k) consistent with every agent's decision
        vector and with D_chi (the joint reading of eq. 5.21); ``minimal``: the subset-minimal ones.
    """

    local: dict[int, list[frozenset[str]]]
    d_chi: np.ndarray
    chi: list[frozenset[str]]
    intersection: list[frozenset[str]]
    global_candidates: tuple[str, ...]
    diagnoses: list[frozenset[str]]
    minimal: list[frozenset[str]]


def _three_valued_masks(tv: np.ndarray) -> tuple[list[int], list[int]]:
    """Per fault: bitmask of rows marked 1, and of rows marked 1 or '*'."""
    return _row_masks(tv == 1), _row_masks(tv != 0)


def _consistent(ones: list[int], anys: list[int], d_mask: int, cols: Sequence[int]) -> bool:
    """Three-valued pattern match of a fault combination's signature with a decision vector
    (bitmask over the rows): a fired row needs a member marked 1 or '*', a silent row no member
    marked 1."""
    o = a = 0
    for j in cols:
        o |= ones[j]
        a |= anys[j]
    return (a & d_mask) == d_mask and not (o & ~d_mask)


def thesis_global_diagnosis(
    decisions, *, matrix=None, max_cardinality: int = 3, dchi_rule: str = "any"
) -> ThesisGlobalDiagnosis:
    """The thesis's local and global decision logic (eq. 5.20-5.22) on a decision vector.

    decisions : bool (19,) in ``MODULE_IDS`` order (or module ids), D = [D^(1), ..., D^(4)].
    matrix : int (19, 26) three-valued signature matrix (0, 1, 2 = '*'); default the thesis's
        tables 6.5-6.8 (:func:`thesis_signature_matrix`).  Pass ``fsm.astype(np.int8)`` to run
        the logic on the derived FSM with every cell read as 1.  An agent's columns are the
        faults marked in its rows.
    dchi_rule : 'any' (default): D_chi^(l) = 1 iff agent l has a fired module, the reading the
        thesis's examples use (in 6.4.2 D_chi^(2) = 1 with D_s^(2) = {f_z,V1}, which eq. 5.20
        read literally would give 0); 'eq5.20': D_chi^(l) = 1 iff a local diagnosis contains a
        fault propagated to the agent (a column of another subsystem) or a sensor of the agent's
        own subsystem that other agents read.
    F^chi is derived from the same matrix: 1 for an agent's own faults it marks, '*' for other
    subsystems' faults it marks.
    """
    d = fired_vector(decisions)
    tv = thesis_signature_matrix() if matrix is None else np.asarray(matrix)
    if tv.shape != (N_MODULES, N_FAULTS):
        raise ValueError(f"matrix must have shape ({N_MODULES}, {N_FAULTS}), got {tv.shape}")
    tv = tv.astype(np.int8)
    agents = tuple(sorted(AGENTS))
    rows = {a: [_MODULE_INDEX[m] for m in AGENTS[a]] for a in agents}
    cols = {a: [j for j in range(N_FAULTS) if (tv[rows[a], j] != 0).any()] for a in agents}
    k = int(max_cardinality)

    ones, anys = _three_valued_masks(tv)
    d_mask = _row_masks(d[:, None])[0]
    local: dict[int, list[frozenset[str]]] = {}
    for a in agents:
        rmask = 0
        for i in rows[a]:
            rmask |= 1 << i
        sets = []
        if d_mask & rmask:
            lo = [x & rmask for x in ones]
            la = [x & rmask for x in anys]
            for r in range(1, k + 1):
                for combo in combinations(cols[a], r):
                    if _consistent(lo, la, d_mask & rmask, combo):
                        sets.append(frozenset(FAULT_IDS[j] for j in combo))
        local[a] = sets

    # propagation decisions
    d_chi = np.zeros(len(agents), dtype=np.int8)
    for r, a in enumerate(agents):
        if dchi_rule == "any":
            d_chi[r] = int(d[rows[a]].any())
        elif dchi_rule == "eq5.20":
            read_elsewhere = {FAULT_IDS[j] for b in agents if b != a for j in cols[b]}
            hit = False
            for s in local[a]:
                for f in s:
                    if fault_agent(f) != a or (fault_class(f) == "sensor" and f in read_elsewhere):
                        hit = True
            d_chi[r] = int(hit)
        else:
            raise ValueError(f"dchi_rule must be 'any' or 'eq5.20', got {dchi_rule!r}")

    fchi = np.zeros((len(agents), N_FAULTS), dtype=np.int8)
    for r, a in enumerate(agents):
        for j in cols[a]:
            fchi[r, j] = 1 if fault_agent(FAULT_IDS[j]) == a else STAR
    chi = []
    relevant = [j for j in range(N_FAULTS) if fchi[:, j].any()]
    c_ones, c_anys = _three_valued_masks(fchi)
    chi_mask = _row_masks(d_chi.astype(bool)[:, None])[0]
    if d_chi.any():
        for r in range(1, k + 1):
            for combo in combinations(relevant, r):
                if _consistent(c_ones, c_anys, chi_mask, combo):
                    chi.append(frozenset(FAULT_IDS[j] for j in combo))
    ds = {s for a in agents for s in local[a]}
    chi_set = set(chi)
    inter = sorted(ds & chi_set, key=diagnosis_sort_key)
    gcand = tuple(f for f in candidates(chi) if f in set(candidates(list(ds))))

    diagnoses = []
    if d.any():
        for r in range(1, k + 1):
            for combo in combinations(range(N_FAULTS), r):
                if _consistent(ones, anys, d_mask, combo) and _consistent(c_ones, c_anys, chi_mask, combo):
                    diagnoses.append(frozenset(FAULT_IDS[j] for j in combo))
    minimal = [s for s in diagnoses if not any(o < s for o in diagnoses)]
    return ThesisGlobalDiagnosis(
        local=local,
        d_chi=d_chi,
        chi=sorted(chi, key=diagnosis_sort_key),
        intersection=inter,
        global_candidates=gcand,
        diagnoses=sorted(diagnoses, key=diagnosis_sort_key),
        minimal=sorted(minimal, key=diagnosis_sort_key),
    )


# ----------------------------------------------------------------------------- streaming state
class DiagnosisState:
    """Latched module decisions and the current minimal diagnoses, updated per sample.

    ``update(decisions, t)`` ORs the decision vector into the latched set (eq. 5.19) and recomputes
    the minimal diagnoses only when the set of fired modules changes.  Options as in
    :func:`minimal_diagnoses`; ``temporal=True`` passes the modules' first detection times (needs
    an exoneration matrix to have an effect; ``settle_s`` None = :func:`default_settle_times`).
    """

    def __init__(
        self,
        *,
        support=None,
        exoneration=None,
        max_cardinality: int | None = 3,
        temporal: bool = False,
        settle_s=None,
        grace_s=0.0,
    ):
        self.support = _support(support)
        self.exoneration = _exoneration(exoneration, self.support)
        self.max_cardinality = max_cardinality
        self.temporal = bool(temporal)
        self.settle_s = default_settle_times() if settle_s is None else settle_s
        self.grace_s = grace_s
        self.n_recomputations = 0
        self.reset()

    def reset(self) -> None:
        self.fired = np.zeros(N_MODULES, dtype=bool)
        self.detection_times = np.full(N_MODULES, np.nan)
        self.first_detection_time = math.nan
        self.diagnoses: list[frozenset[str]] = [frozenset()]
        self._t = -1
        self._next_expiry = math.inf

    @property
    def detected(self) -> bool:
        return bool(self.fired.any())

    @property
    def fired_modules(self) -> tuple[str, ...]:
        return tuple(m for m, f in zip(MODULE_IDS, self.fired) if f)

    @property
    def candidates(self) -> tuple[str, ...]:
        return candidates(self.diagnoses)

    @property
    def classes(self) -> dict[str, str]:
        return candidate_classes(self.diagnoses)

    def update(self, decisions, t: float | None = None) -> bool:
        """Feed one sample's module decisions (bool (19,) or module ids); True if the fired set changed."""
        self._t += 1
        tt = float(self._t if t is None else t)
        new = fired_vector(decisions) & ~self.fired
        if not new.any():
            return self.advance(tt)
        self.fired = self.fired | new
        self.detection_times[new] = tt
        if math.isnan(self.first_detection_time):
            self.first_detection_time = tt
        self._recompute(tt)
        return True

    def advance(self, t: float) -> bool:
        """Move the clock to t without new decisions; recompute when a grace period has expired
        (temporal mode only).  True if the diagnoses were recomputed."""
        if self.temporal and self.fired.any() and t > self._next_expiry:
            self._recompute(float(t))
            return True
        return False

    def _recompute(self, now: float) -> None:
        temporal = self.temporal
        self.diagnoses = minimal_diagnoses(
            self.fired,
            support=self.support,
            exoneration=self.exoneration,
            detection_times=self.detection_times if temporal else None,
            settle_s=self.settle_s,
            max_cardinality=self.max_cardinality,
            now=now if temporal else None,
            grace_s=self.grace_s,
        )
        self.n_recomputations += 1
        if temporal:
            td = np.where(self.fired, self.detection_times, np.inf)
            first = np.where(self.support & self.fired[:, None], td[:, None], np.inf).min(axis=0)
            ends = first[None, :] + np.broadcast_to(np.asarray(self.grace_s, dtype=float), (N_MODULES, N_FAULTS))
            pending = ends[np.isfinite(ends) & (ends >= now)]
            self._next_expiry = float(pending.min()) if len(pending) else math.inf


@dataclass(frozen=True)
class DiagnosisEvent:
    """A change of the fired set: time, sample index, fired modules, minimal diagnoses then."""

    time: float
    index: int
    fired: tuple[str, ...]
    diagnoses: list[frozenset[str]] = field(default_factory=list)


def diagnose_decisions(violations, times=None, **options) -> list[DiagnosisEvent]:
    """Offline diagnosis of a (T, 19) violation record: the events where the fired set changes,
    with the minimal diagnoses from then on (options of :class:`DiagnosisState`).  Only the change
    samples are visited (at most 19)."""
    lat = latch_decisions(violations, times)
    if lat.decisions.ndim != 2:
        raise ValueError("diagnose_decisions takes one run (T, 19)")
    T = lat.decisions.shape[0]
    t = np.arange(T, dtype=float) if times is None else np.asarray(times, dtype=float)
    state = DiagnosisState(**options)
    events = []
    for idx in np.unique(lat.first_index[lat.first_index >= 0]):
        if state.update(lat.decisions[idx], float(t[idx])):
            events.append(DiagnosisEvent(float(t[idx]), int(idx), state.fired_modules, list(state.diagnoses)))
    return events


# ----------------------------------------------------------------------------- thesis section 6.4
@dataclass(frozen=True)
class ThesisExample:
    """A multiple-fault example of section 6.4 as the thesis reports it.

    injected : (fault id, onset s).  epochs : (time from which, fired modules) as printed, the
    module decision vectors D^(l) of the text.  thesis_candidates : the faults of its final global
    diagnosis set D_s^G.  unique : the thesis isolates the injected set uniquely.
    """

    name: str
    injected: tuple[tuple[str, float], ...]
    epochs: tuple[tuple[float, tuple[str, ...]], ...]
    thesis_candidates: tuple[str, ...]
    unique: bool

    @property
    def injected_set(self) -> frozenset[str]:
        return frozenset(f for f, _ in self.injected)

    @property
    def final_fired(self) -> tuple[str, ...]:
        return self.epochs[-1][1]

    def detection_times(self) -> np.ndarray:
        """(19,) first time each module is reported fired (NaN if never)."""
        out = np.full(N_MODULES, np.nan)
        for t, mods in self.epochs:
            for m in mods:
                i = _MODULE_INDEX[m]
                if np.isnan(out[i]):
                    out[i] = t
        return out


THESIS_EXAMPLES: dict[str, ThesisExample] = {
    # 6.4.1: D^(3) = [0 0 0 1 1] from 175 s; from 235 s D^(2) = [0 1 0 1 0 0], D^(4) = [0 1 0 0 0 0].
    # D_s^G = {f_2^(4), f_2^(3), f_4^(3), f_5^(3)} "and any other combination".
    "thesis-6.4.1": ThesisExample(
        "thesis-6.4.1",
        (("S3.4", 175.0), ("S4.2", 235.0)),
        ((175.0, ("M3.4", "M3.5")), (235.0, ("M2.2", "M2.4", "M3.4", "M3.5", "M4.2"))),
        ("S3.2", "S3.4", "S3.5", "S4.2"),
        False,
    ),
    # 6.4.2: D^(2) = [0 0 1 1 0 0] at 146.1 s, [1 1 1 1 0 0] at 201.6 s, D^(1) = [1 1] at 207.1 s.
    "thesis-6.4.2": ThesisExample(
        "thesis-6.4.2",
        (("bore_damage", 5.0), ("valve_seizing", 200.0)),
        (
            (146.1, ("M2.3", "M2.4")),
            (201.6, ("M2.1", "M2.2", "M2.3", "M2.4")),
            (207.1, ("M1.1", "M1.2", "M2.1", "M2.2", "M2.3", "M2.4")),
        ),
        ("valve_seizing", "bore_damage"),
        True,
    ),
    # 6.4.3: D^(2) = [0 1 0 0 0 0] from 20 s; D^(4) = [1 1 0 0 0 0] from 156.8 s.
    "thesis-6.4.3": ThesisExample(
        "thesis-6.4.3",
        (("S2.2", 20.0), ("compressor_seal_leak", 30.0)),
        ((20.0, ("M2.2",)), (156.8, ("M2.2", "M4.1", "M4.2"))),
        ("S2.2", "compressor_seal_leak"),
        True,
    ),
    # 6.4.4: D^(3) = [0 1 0 0 0], D^(4) = [0 1 0 0 0 0] from 15 s; D^(3) = [0 1 1 1 0] from 104.6 s.
    # D_s^G = {f_2^(3), f_4^(3), f_2^(4), {f_2^(3), f_4^(3)}, {f_4^(3), f_2^(4)}, {f_2^(3), f_2^(4)},
    #          {f_Tsl, f_2^(4)}, {f_Tsl, f_2^(3)}, {f_Tsl, f_4^(3)}}.
    "thesis-6.4.4": ThesisExample(
        "thesis-6.4.4",
        (("S3.2", 15.0), ("turbine_lubrication_loss", 30.0)),
        ((15.0, ("M3.2", "M4.2")), (104.6, ("M3.2", "M3.3", "M3.4", "M4.2"))),
        ("S3.2", "S3.4", "S4.2", "turbine_lubrication_loss"),
        False,
    ),
}
