"""Presets, overrides and the checks that stop an unusable parameter set early."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyro_fmu.model.parameters import (
    PRESETS,
    ParameterError,
    UnstablePlantWarning,
    check_parameters,
    max_growth_rate,
    preset,
    validate_for_plant,
)


def test_park_horowitz_is_the_normalized_benchmark():
    p = preset("park-horowitz")
    assert math.isclose(p.kxx, (2 * math.pi * 3000) ** 2, rel_tol=2e-3)
    assert math.isclose(p.kyy, (2 * math.pi * 3674) ** 2, rel_tol=2e-3)
    assert math.isclose(p.kxy, 7.10e7, rel_tol=1e-3)
    assert (p.dxx, p.dyy, p.dxy, p.m) == pytest.approx((10.0, 10.0, 2.0, 1.8e-7))
    assert max_growth_rate(p) < 0


def test_table1_as_printed_is_refused_with_eigenvalues_and_a_remedy():
    with pytest.raises(ParameterError) as info:
        validate_for_plant(PRESETS["patent-table1"])
    text = str(info.value)
    assert "not positive definite" in text
    assert "-1.967e+08" in text and "5.84e+08" in text  # eigenvalues of K, Table 1
    assert "park-horowitz" in text


def test_table1_corrected_warns_with_its_growth_rate():
    p = preset("patent-table1-corrected")
    assert p.kxy == pytest.approx(7.10e7, rel=1e-3)
    with pytest.warns(UnstablePlantWarning, match=r"grows at 1\.8 1/s"):
        validate_for_plant(p)
    eig = np.linalg.eigvals(np.array([[0, 1, 0, 0], [-p.kxx, -p.dxx, -p.kxy, -p.dxy],
                                      [0, 0, 0, 1], [-p.kxy, -p.dxy, -p.kyy, -p.dyy]]))
    assert max(eig.real) == pytest.approx(1.80, abs=0.01)


def test_overrides_apply_and_bad_names_or_values_are_named():
    assert preset(kxy=1e7).kxy == 1e7
    with pytest.raises(ParameterError, match=r"unknown parameter\(s\) \['kzz'\]"):
        preset(kzz=1.0)
    with pytest.raises(ParameterError, match=r"kxx='abc' is not a number"):
        preset(kxx="abc")
    with pytest.raises(ParameterError, match="must be finite"):
        preset(dxx=float("nan"))
    with pytest.raises(ParameterError, match=r"unknown preset 'nope'.*park-horowitz"):
        preset("nope")
    with pytest.raises(ParameterError, match=r"mass m=-1\.0 kg must be > 0"):
        validate_for_plant(preset(m=-1.0))


def test_the_parameter_limits_are_the_cores() -> None:
    """K_MAX and D_MAX are declared once (gyro_fmu.core.structs.plant) for the FMUs' max and
    the core's checks (GYRO_K_MAX, GYRO_D_MAX of the generated gyro_structs.h): the core
    accepts each limit itself and refuses the next double above it."""
    from gyro_fmu.model.parameters import D_MAX, K_MAX

    base = PRESETS["park-horowitz"]
    for name, limit in (("kxy", K_MAX), ("dxy", D_MAX)):
        at = check_parameters(base.with_overrides(**{name: -limit}))
        assert not any(f"|{name}| <=" in p for p in at), at
        above = check_parameters(base.with_overrides(**{name: math.nextafter(limit, math.inf)}))
        assert above and f"|{name}| <= {limit:g}" in above[0], above
