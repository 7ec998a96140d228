"""Supervised diagnoser: a small GRU over the episode's residual features.

Model (:class:`GRUDiagnoser`): per decision, the observation features (115 without sensors), and
optionally EWMAs of the signed residual means the model computes itself (``ewma_features``,
``ewma_taus``), are standardised (mean and scale of the training data, stored with the weights), pass a
linear layer + ReLU and a
one-layer GRU that carries the episode's history (causal: the output at decision k depends only
on decisions 0..k), and a linear head gives 27 logits: one per fault id (multi-label: which
faults are active) and one for "some fault is active".  Features listed in ``drop_features`` are
masked out: by default the episode clock ``time_fraction``, which would otherwise let the model
learn the prior "late in an episode there is usually a fault" (onsets are drawn in 20-200 s) and
raise its fault probability on long fault-free stretches without any evidence.

Training data: ``marine-fdi dataset`` exports of scenario *presets* (never of the evaluation
suites); labels are the ``active`` arrays (a fault counts from its onset on).  Loss: binary cross
entropy on every valid decision, the "fault active" logit weighted ``alarm_weight``.

Declaration (:class:`marine_fdi_env.training.agents.ClassifierAgent`): the alarm is raised when the "fault
active" probability passes ``alarm_threshold`` and then stays on (latched: faults do not go away
by themselves in the suites, and a flickering alarm would count one false alarm per rising
edge); the threshold is calibrated on fault-free episodes for a target false-alarm rate
(:func:`calibrate_threshold`).  While the alarm is on, the faults with probability >=
``isolation_threshold`` are declared (``unknown`` when none is).  With a conformal isolation
calibration (:func:`calibrate_isolation`), that set is declared only when it is as decisive as
the most probable sets of all but ``alpha`` of the held-in faulty episodes; otherwise the agent
abstains: alarm on, ``unknown`` (:func:`conformal_declaration`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from marine_fdi_env.engine.faults import FAULT_IDS

__all__ = [
    "GRUDiagnoser",
    "TrainResult",
    "train_classifier",
    "fit_epochs",
    "calibrate_threshold",
    "load_dataset",
    "episode_scores",
    "set_score",
    "calibrate_isolation",
    "conformal_sets",
    "conformal_declaration",
    "alarm_balance_weights",
]

N_FAULTS = len(FAULT_IDS)


class GRUDiagnoser(nn.Module):
    """Causal GRU: (B, T, D) features -> (B, T, 27) logits (26 faults, then "some fault").

    With ``ewma_idx`` (feature indices, normally the 19 ``signed_mean_ratio`` features) and
    ``ewma_taus`` (time constants in decisions), the model first appends exponentially weighted
    moving averages of those features (one per index and time constant, started at 0 at the
    episode start): the agent's own accumulation of the small, persistent residual bias of an
    incipient fault, which a single decision period's mean hides in the noise.  The state passed
    between calls is ``(gru_state, ewma_state)``.
    """

    def __init__(self, n_features: int, hidden: int = 64, embed: int = 64, ewma_idx=(), ewma_taus=()) -> None:
        super().__init__()
        self.n_features = int(n_features)
        self.hidden = int(hidden)
        self.embed = int(embed)
        self.ewma_idx = [int(i) for i in ewma_idx]
        self.ewma_taus = [float(t) for t in ewma_taus] if self.ewma_idx else []
        n_in = self.n_features + len(self.ewma_idx) * len(self.ewma_taus)
        self.n_inputs = n_in
        self.register_buffer("mean", torch.zeros(n_in))
        self.register_buffer("scale", torch.ones(n_in))
        self.register_buffer("mask", torch.ones(n_in))  # 0: feature ignored (e.g. the clock)
        self.inp = nn.Linear(n_in, embed)
        self.gru = nn.GRU(embed, hidden, batch_first=True)
        self.head = nn.Linear(hidden, N_FAULTS + 1)

    def augment(self, x: torch.Tensor, state: torch.Tensor | None = None):
        """(B, T, D) -> (B, T, D + n_ewma) and the EWMA state (B, n_ewma) after the last step."""
        if not self.ewma_idx:
            return x, None
        sel = x[..., self.ewma_idx]  # (B, T, k)
        k = sel.shape[-1]
        alpha = torch.tensor([1.0 / t for t in self.ewma_taus], dtype=x.dtype).repeat_interleave(k)
        src = sel.repeat(1, 1, len(self.ewma_taus))  # (B, T, k * n_taus), tau-major
        s = torch.zeros(x.shape[0], src.shape[-1], dtype=x.dtype) if state is None else state
        out = []
        for t in range(x.shape[1]):
            s = s + alpha * (src[:, t] - s)
            out.append(s)
        return torch.cat([x, torch.stack(out, 1)], -1), s

    def core(self, xa: torch.Tensor, h: torch.Tensor | None = None):
        z = torch.relu(self.inp((xa - self.mean) / self.scale * self.mask))
        y, h = self.gru(z, h)
        return self.head(y), h

    def forward(self, x: torch.Tensor, h=None):
        gh, es = h if isinstance(h, tuple) else (h, None)
        xa, es = self.augment(x, es)
        logits, gh = self.core(xa, gh)
        return logits, ((gh, es) if self.ewma_idx else gh)


@dataclass
class TrainResult:
    model: GRUDiagnoser
    curve: list[dict]
    cpu_s: float


def load_dataset(path) -> dict:
    """The arrays of a ``marine-fdi dataset`` export (``dataset.npz`` or its directory)."""
    from pathlib import Path

    p = Path(path)
    if p.is_dir():
        p = p / "dataset.npz"
    with np.load(p) as z:
        return {k: z[k] for k in ("obs", "active", "valid")}


def _targets(active: np.ndarray) -> np.ndarray:
    return np.concatenate([active, active.any(axis=-1, keepdims=True)], axis=-1).astype(np.float32)


def train_classifier(
    data: dict,
    *,
    seed: int,
    hidden: int = 64,
    embed: int = 64,
    epochs: int = 30,
    batch_size: int = 32,
    lr: float = 2e-3,
    weight_decay: float = 1e-5,
    alarm_weight: float = 4.0,
    val_fraction: float = 0.1,
    drop_features=(),
    feature_names=None,
    ewma_features=(),
    ewma_taus=(),
    episode_weight=None,
    balance_alarm: bool = False,
    lr_schedule: str = "constant",
    log=print,
) -> TrainResult:
    """Train a :class:`GRUDiagnoser` on dataset arrays (``obs``, ``active``, ``valid``); seeded.

    ``balance_alarm``: weight the "some fault" term so that, at every decision index, the decisions
    with and without an active fault weigh the same (:func:`alarm_balance_weights`): the alarm
    output then carries the evidence, not the prior "a fault is likelier late in an episode" that a
    recurrent network can learn by counting decisions.

    ``lr_schedule``: ``"constant"`` (``lr`` throughout) or ``"cosine"`` (``lr`` annealed to 0 over the
    epochs along a half cosine, stepped once per epoch: the last epochs average out the minibatch noise,
    so the final weights are not one noisy step of a walk at full learning rate)."""
    if lr_schedule not in ("constant", "cosine"):
        raise ValueError(f"lr_schedule must be 'constant' or 'cosine', got {lr_schedule!r}")
    c0 = time.process_time()
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    obs = torch.as_tensor(data["obs"], dtype=torch.float32)
    y = torch.as_tensor(_targets(data["active"]))
    valid = torch.as_tensor(data["valid"], dtype=torch.float32)
    E, T, D = obs.shape
    perm = rng.permutation(E)
    n_val = int(round(val_fraction * E)) if E >= 10 else 0
    val_idx, tr_idx = perm[:n_val], perm[n_val:]
    names = list(feature_names) if feature_names is not None else []
    ewma_idx = [i for i, n in enumerate(names) if any(n.endswith("." + f) for f in ewma_features)]
    model = GRUDiagnoser(D, hidden=hidden, embed=embed, ewma_idx=ewma_idx, ewma_taus=ewma_taus)
    with torch.no_grad():  # the EWMA inputs are fixed functions of the observations: computed once
        obs = torch.cat([model.augment(obs[s : s + 256])[0] for s in range(0, E, 256)])
    ew = torch.ones(E) if episode_weight is None else torch.as_tensor(episode_weight, dtype=torch.float32)
    flat = obs[tr_idx][valid[tr_idx] > 0]
    model.mean.copy_(flat.mean(0))
    model.scale.copy_(flat.std(0).clamp_min(1e-3))
    for name in drop_features:
        model.mask[list(feature_names).index(name)] = 0.0
    opt = torch.optim.Adam(model.parameters(), lr=lr, weight_decay=weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=epochs) if lr_schedule == "cosine" else None
    w = torch.ones(N_FAULTS + 1)
    w[-1] = alarm_weight
    bce = nn.BCEWithLogitsLoss(reduction="none")
    wa = torch.as_tensor(
        alarm_balance_weights(data["active"].any(-1), data["valid"])
        if balance_alarm
        else np.ones(valid.shape, np.float32)
    )

    def loss_of(idx):
        logits, _ = model.core(obs[idx])
        terms = bce(logits, y[idx]) * w
        terms[..., -1] = terms[..., -1] * wa[idx]
        per = terms.sum(-1)
        m = valid[idx] * ew[idx, None]
        return (per * m).sum() / m.sum().clamp_min(1.0)

    curve = fit_epochs(
        model, opt, loss_of, tr_idx, val_idx, epochs=epochs, batch_size=batch_size, rng=rng, c0=c0, sched=sched, log=log
    )
    return TrainResult(model, curve, time.process_time() - c0)


def fit_epochs(
    model, opt, loss_of, tr_idx, val_idx, *, epochs: int, batch_size: int, rng, c0: float, sched=None, log=print
) -> list[dict]:
    """The supervised training loop of the classifier and the decentralised teams: each epoch, minibatches of
    the training episodes in a fresh order from ``rng`` (an ``opt`` step on ``loss_of(idx)``, gradients clipped
    at norm 1), ``sched`` stepped, then the loss on ``val_idx``; returns the learning curve (one row per epoch,
    CPU s since ``c0``) with ``model`` left in eval mode."""
    curve = []
    for ep in range(epochs):
        model.train()
        order = rng.permutation(tr_idx)
        tot, nb = 0.0, 0
        for s in range(0, len(order), batch_size):
            opt.zero_grad()
            loss = loss_of(order[s : s + batch_size])
            loss.backward()
            nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            opt.step()
            tot += loss.item()
            nb += 1
        if sched is not None:
            sched.step()
        row = {"epoch": ep + 1, "train_loss": tot / max(nb, 1), "cpu_s": time.process_time() - c0}
        if len(val_idx):
            model.eval()
            with torch.no_grad():
                row["val_loss"] = float(loss_of(val_idx))
        curve.append(row)
        if log:
            log(
                f"epoch {ep + 1:3d}  train {row['train_loss']:.4f}"
                + (f"  val {row['val_loss']:.4f}" if len(val_idx) else "")
                + f"  cpu {row['cpu_s']:.0f} s"
            )
    model.eval()
    return curve


def alarm_balance_weights(fault: np.ndarray, valid: np.ndarray, cap: float = 5.0) -> np.ndarray:
    """Weights (E, T) of the "some fault" term: at each decision index t, ``N_t / (2 n_t)`` for the
    n_t valid decisions of its class (fault active or not) among the N_t valid ones, so both classes
    weigh half; at most ``cap``; 1 where a class is absent at t."""
    fault = fault & valid
    n_pos, n_all = fault.sum(axis=0).astype(float), valid.sum(axis=0).astype(float)
    n_neg = n_all - n_pos
    both = (n_pos > 0) & (n_neg > 0)
    w_pos = np.where(both, n_all / (2 * np.maximum(n_pos, 1)), 1.0)
    w_neg = np.where(both, n_all / (2 * np.maximum(n_neg, 1)), 1.0)
    return np.minimum(np.where(fault, w_pos[None, :], w_neg[None, :]), cap).astype(np.float32)


@torch.no_grad()
def episode_scores(model: GRUDiagnoser, obs: np.ndarray, batch: int = 64) -> np.ndarray:
    """Probabilities (E, T, 27) for whole episodes (E, T, D)."""
    out = []
    for s in range(0, len(obs), batch):
        logits, _ = model(torch.as_tensor(obs[s : s + batch], dtype=torch.float32))
        out.append(torch.sigmoid(logits).numpy())
    return np.concatenate(out)


def calibrate_threshold(
    alarm_prob: np.ndarray, valid: np.ndarray, period_s: float = 1.0, target_per_hour: float = 0.0, margin: float = 1.0
) -> dict:
    """Alarm threshold for at most ``target_per_hour`` false alarms on fault-free episodes.

    ``alarm_prob`` (E, T): the "some fault" probability of fault-free episodes.  With the latched
    alarm an episode raises one false alarm iff its maximum passes the threshold, so the
    threshold is set above the maximum of all but ``floor(target * hours)`` episodes; ``margin``
    (>= 0) then moves it further up in log-odds (``logit(thr) + margin``), a safety distance for
    operating conditions the calibration episodes do not cover.
    """
    p = np.where(valid, alarm_prob, 0.0)
    peaks = np.sort(p.max(axis=1))[::-1]
    hours = float(valid.sum()) * period_s / 3600.0
    allowed = int(math.floor(target_per_hour * hours + 1e-9))
    base = float(peaks[allowed]) if allowed < len(peaks) else 0.0
    base = min(max(base, 1e-6), 1 - 1e-6)
    logit = math.log(base / (1 - base)) + margin
    thr = 1.0 / (1.0 + math.exp(-logit))
    return {
        "alarm_threshold": thr,
        "calibration_peak": base,
        "calibration_hours": hours,
        "calibration_episodes": int(len(peaks)),
        "target_false_alarms_per_hour": target_per_hour,
        "margin_logodds": margin,
    }


def set_score(p: np.ndarray, members: np.ndarray) -> np.ndarray:
    """Nonconformity of the fault set ``members`` (.., 26) bool under fault probabilities ``p`` (.., 26):
    ``max(1 - min over members of p, max over the others of p)``: 0 when the network is sure of
    exactly that set, above 0.5 when it leans to another one (1 for an empty set)."""
    inside = np.where(members, 1.0 - p, 0.0).max(axis=-1)
    inside = np.where(members.any(axis=-1), inside, 1.0)
    outside = np.where(members, 0.0, p).max(axis=-1)
    return np.maximum(inside, outside)


def calibrate_isolation(
    probs: np.ndarray, active: np.ndarray, valid: np.ndarray, alpha: float, isolation_threshold: float = 0.5
) -> dict:
    """Split-conformal quantile of :func:`set_score` of the *most probable* fault set (the faults at or above
    ``isolation_threshold``) at the last decision of held-in faulty episodes that have one (``probs``
    (E, T, 27), ``active`` (E, T, 26), ``valid`` (E, T)): the ``ceil((n + 1)(1 - alpha))``-th smallest of
    the n scores (1.0 when that exceeds n).  On exchangeable episodes the most probable set of a new
    faulty episode then scores within the quantile with probability >= 1 - alpha: the agent
    (:func:`conformal_declaration`) abstains on at most ``alpha`` of the episodes like the held-in ones,
    and more often on evidence less decisive than theirs."""
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"isolation_alpha must lie in (0, 1), got {alpha!r}")
    last = valid.sum(axis=1) - 1
    rows = np.arange(len(probs))
    faulty = active[rows, last].any(axis=1) & (last >= 0)
    p = probs[rows, last, :N_FAULTS]
    best = p >= isolation_threshold
    scores = np.sort(set_score(p, best)[faulty & best.any(axis=1)])
    n = len(scores)
    k = int(math.ceil((n + 1) * (1.0 - alpha)))
    q = float(scores[k - 1]) if 0 < k <= n else 1.0
    return {
        "alpha": float(alpha),
        "score": "most probable set",
        "quantile": q,
        "episodes": int(n),
        "declared_in_calibration": float(np.mean(scores <= q)) if n else None,
    }


def conformal_sets(p: np.ndarray, isolation_threshold: float, quantile: float) -> np.ndarray:
    """The fault sets to declare from fault probabilities ``p`` (..., 26), bool (..., 26): the most probable
    set (the faults at or above ``isolation_threshold``) where its :func:`set_score` is within the conformal
    ``quantile`` of :func:`calibrate_isolation`; the empty set (abstain: ``unknown``) where no fault reaches
    the threshold or the set is less decisive than that of ``1 - alpha`` of the held-in faulty episodes."""
    best = p >= isolation_threshold
    return best & (set_score(p, best) <= quantile)[..., None]


def conformal_declaration(p: np.ndarray, isolation_threshold: float, quantile: float) -> np.ndarray | None:
    """:func:`conformal_sets` of one decision's probabilities ``p`` (26,); ``None`` where it abstains."""
    best = conformal_sets(p, isolation_threshold, quantile)
    return best if best.any() else None
