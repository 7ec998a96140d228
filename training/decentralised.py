"""Learned decentralised diagnosers of the multi-agent track: local encoders and a global decoder.

One GRU per local agent reads only its own modules' inputs and sends a message under the budget; a
GRU global agent reads only the four messages and gives the probabilities of the 26 faults and of
"some fault" (the ``classifier``'s head).  Trained centrally, run decentrally: the five networks
are trained together by the classifier's loss through the messages (binary cross entropy per fault
and for "some fault", the alarm term weighted and balanced over time: :mod:`.classifier`), and at run
time each is a policy of its own agent (:class:`DecentralisedLocal`, :class:`DecentralisedGlobal`).

* **Local inputs** (:class:`~marine_fdi_env.training.features.AgentFeatures` with ``noise_window`` 4,
  the ``classifier``'s): per module of the local's subsystem the period's signed mean, mean and
  maximum of r/thr over the module's noise level from the episode's first 4 decisions, and EWMAs of
  the signed mean (5, 20, 60 decisions): six inputs per module, each computed from that module's own
  observation features only.
* **Messages**: ``bits`` budgets: the sign of a linear head (1 where positive), trained with the
  straight-through estimator (the forward pass sends the bit, the backward pass the gradient of a
  sigmoid); ``numbers`` budgets: ``MESSAGE_BOUND tanh`` of the head.  Everything a local sends is the
  message: nothing else leaves it.  ``locals: thesis`` (the ``decision`` budget only): the locals are
  the thesis's, sending their decision vectors D^(l) (the latched ``fired`` features of their modules,
  :class:`ThesisBits`), and only the global is trained (``dec-global-decision``).
* **Declaration**: the ``classifier``'s rule (:class:`~marine_fdi_env.training.agents.ClassifierAgent`):
  a latched alarm when P(some fault) passes a threshold set for zero false alarms on fault-free
  calibration episodes plus a margin, and the most probable fault set unless it is less decisive than
  on 1 - alpha of held-in faulty episodes (split conformal), else ``unknown``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from marine_fdi_env.engine.faults import FAULT_IDS
from marine_fdi_env.multiagent.budgets import MESSAGE_BOUND, MessageBudget
from marine_fdi_env.multiagent.roles import LOCAL_AGENTS, local_modules

from .classifier import alarm_balance_weights, fit_epochs

__all__ = [
    "LocalEncoder",
    "ThesisBits",
    "GlobalDecoder",
    "DecentralisedNet",
    "TrainResult",
    "train_decentralised",
    "local_inputs",
]

N_FAULTS = len(FAULT_IDS)
PER_MODULE_INPUTS = 6  # AgentFeatures (noise_window 4): 3 invariant features + 3 EWMAs per module
# what the locals are: trained encoders, or the thesis's decision vectors (only the global learns)
LOCALS = ("learned", "thesis")


def local_inputs(input_names: list[str], agent: str) -> np.ndarray:
    """The columns of the invariant inputs (``AgentFeatures.input_names()`` of the whole observation) that
    belong to a local agent's modules, in input order."""
    mods = set(local_modules(agent))
    cols = [j for j, name in enumerate(input_names) if _module_of(name) in mods]
    if len(cols) != PER_MODULE_INPUTS * len(mods):
        raise ValueError(f"{agent}: expected {PER_MODULE_INPUTS} inputs per module, got {len(cols)}")
    return np.array(cols, dtype=np.int64)


def _module_of(name: str) -> str:
    inner = name[name.index("(") + 1 : name.rindex(")")] if "(" in name else name
    return ".".join(inner.split(".")[:2])


class LocalEncoder(nn.Module):
    """One local agent: (B, T, 6 n_l) inputs -> (B, T, size) messages; ``bits``: 0/1 by the
    straight-through estimator, ``numbers``: within ±MESSAGE_BOUND."""

    def __init__(self, n_in: int, size: int, kind: str, hidden: int = 32, embed: int = 32) -> None:
        super().__init__()
        self.kind = kind
        self.register_buffer("mean", torch.zeros(n_in))
        self.register_buffer("scale", torch.ones(n_in))
        self.inp = nn.Linear(n_in, embed)
        self.gru = nn.GRU(embed, hidden, batch_first=True)
        self.head = nn.Linear(hidden, size)

    def forward(self, x: torch.Tensor, h=None):
        z, h = self.gru(torch.relu(self.inp((x - self.mean) / self.scale)), h)
        logits = self.head(z)
        if self.kind == "bits":
            soft = torch.sigmoid(logits)
            hard = (logits > 0).to(logits.dtype)
            return hard + (soft - soft.detach()), h  # exactly the bits forward, the sigmoid's gradient backward
        return MESSAGE_BOUND * torch.tanh(logits), h


class ThesisBits(nn.Module):
    """A local that sends the thesis's decision vector D^(l) (eq. 5.19): its inputs are its modules' latched
    ``fired`` features (0/1), sent as they are; no parameters (``locals: thesis`` in the hyperparameters)."""

    kind = "bits"

    def forward(self, x: torch.Tensor, h=None):
        return x, h


class GlobalDecoder(nn.Module):
    """The global agent: (B, T, total) messages -> (B, T, 27) logits (26 faults, then "some fault")."""

    def __init__(self, n_in: int, hidden: int = 64, embed: int = 64) -> None:
        super().__init__()
        self.inp = nn.Linear(n_in, embed)
        self.gru = nn.GRU(embed, hidden, batch_first=True)
        self.head = nn.Linear(hidden, N_FAULTS + 1)

    def forward(self, m: torch.Tensor, h=None):
        z, h = self.gru(torch.relu(self.inp(m)), h)
        return self.head(z), h


class DecentralisedNet(nn.Module):
    """The four local encoders and the global decoder, for training (inputs of every local side by side)."""

    def __init__(
        self, budget: MessageBudget, columns: dict, hidden_local: int, hidden_global: int, locals_: str = "learned"
    ) -> None:
        super().__init__()
        if locals_ not in LOCALS:
            raise ValueError(f"locals must be one of {', '.join(LOCALS)}, got {locals_!r}")
        if locals_ == "thesis" and budget.name != "decision":
            raise ValueError(f"the thesis's locals send decision vectors: budget 'decision', got {budget.name!r}")
        self.budget = budget
        self.columns = {a: torch.as_tensor(c) for a, c in columns.items()}
        self.locals = nn.ModuleDict(
            {
                a: ThesisBits()
                if locals_ == "thesis"
                else LocalEncoder(len(columns[a]), budget.size(a), budget.kind, hidden_local, hidden_local)
                for a in LOCAL_AGENTS
            }
        )
        self.glob = GlobalDecoder(budget.total_size, hidden_global, hidden_global)

    def forward(self, x: torch.Tensor):
        msgs = [self.locals[a](x[..., self.columns[a]])[0] for a in LOCAL_AGENTS]
        return self.glob(torch.cat(msgs, -1))[0]


@dataclass
class TrainResult:
    net: DecentralisedNet
    curve: list[dict]
    cpu_s: float


def train_decentralised(
    x: np.ndarray,
    active: np.ndarray,
    valid: np.ndarray,
    budget: MessageBudget,
    columns: dict,
    *,
    seed: int,
    hidden_local: int = 32,
    hidden_global: int = 64,
    epochs: int = 12,
    batch_size: int = 32,
    lr: float = 2e-3,
    weight_decay: float = 1e-5,
    alarm_weight: float = 4.0,
    val_fraction: float = 0.1,
    locals_: str = "learned",
    log=print,
) -> TrainResult:
    """Train a :class:`DecentralisedNet` end to end on invariant inputs ``x`` (E, T, 114) with labels
    ``active`` (E, T, 26) and ``valid`` (E, T); seeded (torch and numpy).  With ``locals_="thesis"``
    ``x`` is the 19 ``fired`` features (E, T, 19) and only the global is trained."""
    c0 = time.process_time()
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    X = torch.as_tensor(x, dtype=torch.float32)
    y = torch.as_tensor(np.concatenate([active, active.any(-1, keepdims=True)], -1).astype(np.float32))
    v = torch.as_tensor(valid, dtype=torch.float32)
    E = len(X)
    perm = rng.permutation(E)
    n_val = int(round(val_fraction * E)) if E >= 10 else 0
    val_idx, tr_idx = perm[:n_val], perm[n_val:]
    net = DecentralisedNet(budget, columns, hidden_local, hidden_global, locals_)
    flat = X[tr_idx][v[tr_idx] > 0]
    for a in LOCAL_AGENTS if locals_ == "learned" else ():
        sel = flat[:, net.columns[a]]
        net.locals[a].mean.copy_(sel.mean(0))
        net.locals[a].scale.copy_(sel.std(0).clamp_min(1e-3))
    opt = torch.optim.Adam(net.parameters(), lr=lr, weight_decay=weight_decay)
    w = torch.ones(N_FAULTS + 1)
    w[-1] = alarm_weight
    bce = nn.BCEWithLogitsLoss(reduction="none")
    wa = torch.as_tensor(alarm_balance_weights(active.any(-1), valid))

    def loss_of(idx):
        terms = bce(net(X[idx]), y[idx]) * w
        terms[..., -1] = terms[..., -1] * wa[idx]
        m = v[idx]
        return (terms.sum(-1) * m).sum() / m.sum().clamp_min(1.0)

    curve = fit_epochs(
        net, opt, loss_of, tr_idx, val_idx, epochs=epochs, batch_size=batch_size, rng=rng, c0=c0, log=log
    )
    return TrainResult(net, curve, time.process_time() - c0)


@torch.no_grad()
def episode_probabilities(net: DecentralisedNet, x: np.ndarray, batch: int = 64) -> np.ndarray:
    """Probabilities (E, T, 27) of whole episodes of inputs (E, T, 114)."""
    out = []
    for s in range(0, len(x), batch):
        out.append(torch.sigmoid(net(torch.as_tensor(x[s : s + batch], dtype=torch.float32))).numpy())
    return np.concatenate(out)
