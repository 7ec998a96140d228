"""The floats-only model constants of the compiled kernels (``engine.constants.kernel_constants``)."""

from __future__ import annotations

import numpy as np
import pytest
from test_submodels import ALL_ON

from marine_fdi_env.engine.constants import KernelConstants, ModelConstants, kernel_constants, model_constants
from marine_fdi_env.engine.model import HEALTHY_PF, N_ALG, solve_algebraic, solve_algebraic_kernel
from marine_fdi_env.engine.params import load_params


def _constants(sub):
    p = load_params("thesis-12v28")
    return model_constants(p if sub is None else p.replace(submodels=sub))


@pytest.mark.parametrize("sub", [None, ALL_ON], ids=["base", "all-submodels"])
def test_kernel_constants_are_the_floats_of_the_model_constants(sub):
    c = _constants(sub)
    kc, csm = kernel_constants(c)
    assert type(kc) is KernelConstants
    assert all(type(v) is float for v in kc)
    assert set(ModelConstants._fields) - set(KernelConstants._fields) == {"wg_u", "wg_a", "bp_u", "bp_b"}
    for f in KernelConstants._fields:
        assert getattr(kc, f) == getattr(c, f), f
    assert csm is (None if sub is None else c)  # the full constants only where a gas-path submodel is on
    again = kernel_constants(c)
    assert again[0] is kc and again[1] is csm  # kept per object
    other = object()
    assert kernel_constants(other) == (other, other)


@pytest.mark.parametrize("sub", [None, ALL_ON], ids=["base", "all-submodels"])
def test_kernel_form_of_the_algebraic_solve_gives_the_same_numbers(sub):
    c = _constants(sub)
    kc, csm = kernel_constants(c)
    pf = HEALTHY_PF.copy()
    pf[3], pf[6] = 5.0, 2.0
    for u in (0.3, 0.7, 1.0):
        x1, x3, x4 = u * c.x1_nom_kg, 1.0e5 + u * 2.5e5, 1.0e5 + u * 3.0e5
        a, b = np.empty(N_ALG), np.empty(N_ALG)
        for sweeps in (1, 2, 3):
            solve_algebraic(c, x1, x3, x4, pf, c.n_nom_rev_s, sweeps, a)
            solve_algebraic_kernel(kc, csm, x1, x3, x4, pf, c.n_nom_rev_s, sweeps, b)
            assert np.array_equal(a, b, equal_nan=True), (u, sweeps)


@pytest.mark.parametrize("name", ["thesis-12v28", "wartsila-6l46"])
@pytest.mark.parametrize("sub", [None, ALL_ON], ids=["base", "all-submodels"])
def test_constants_at_another_ambient_state_are_the_recomputed_ones_bit_for_bit(name, sub):
    """A validation fit runs each measured row at its own ambient state from the engine's constants
    (``constants_at_ambient``): every field must equal a full ``model_constants`` of the engine at that state, so
    that a constant added later that depends on the ambient state fails here rather than bending fits."""
    from marine_fdi_env.engine.constants import constants_at_ambient

    p = load_params(name)
    p = p if sub is None else p.replace(submodels=sub)
    at = p.replace(validate=False, p_amb_Pa=p.p_amb_Pa * 1.0137, T_amb_K=p.T_amb_K + 11.3, p_ex_Pa=p.p_ex_Pa + 2417.0)
    fast, full = constants_at_ambient(model_constants(p), at), model_constants(at)
    assert type(fast) is ModelConstants
    for f in ModelConstants._fields:
        a, b = getattr(fast, f), getattr(full, f)
        assert np.array_equal(a, b) if isinstance(b, np.ndarray) else (type(a) is type(b) and a == b), f
    if sub is not None:  # the intercooler's nominal outlet temperature is the one derived constant that moves
        assert fast.ic_tco_nom != model_constants(p).ic_tco_nom
