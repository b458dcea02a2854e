"""Names that moved to the ground floor still resolve where they were, with a DeprecationWarning."""

from __future__ import annotations

import importlib
import warnings

import pytest

import tactilab.core as core
import tactilab.data_schemas as records

BATCH_NAMES = ["BatchReport", "batch_client", "read_result", "result_path", "run_batch", "stable_hash", "task_rng",
               "write_netcdf_atomic"]


@pytest.mark.parametrize("name", BATCH_NAMES)
def test_the_batch_names_moved_to_core_and_warn_at_their_old_face(name):
    with pytest.warns(DeprecationWarning, match=rf"tactilab.data_schemas.{name} moved to tactilab.core; import it "
                                                rf"from there \('from tactilab.core import {name}'\): the old name "
                                                r"goes in tactilab 0.2.0"):
        old = getattr(records, name)
    assert old is getattr(core, name)
    assert name not in records.__all__ and name not in dir(records)  # new code does not find them


def test_every_use_warns_and_the_warning_points_at_the_callers_line():
    for _ in range(2):
        with pytest.warns(DeprecationWarning) as caught:
            from tactilab.data_schemas import run_batch  # noqa: F401
        assert caught[0].filename == __file__


@pytest.mark.parametrize(("module", "name"), [("batch", "run_batch"), ("batch", "unquote_key"),
                                              ("batch_cluster", "local_cluster"),
                                              ("batch_cluster", "BATCH_CLUSTER_CONFIG")])
def test_the_old_modules_forward_every_name_with_a_warning(module, name):
    old = importlib.import_module(f"tactilab.data_schemas.{module}")
    with pytest.warns(DeprecationWarning, match=rf"tactilab.data_schemas.{module}.{name} moved to "
                                                rf"tactilab.core.{module}"):
        value = getattr(old, name)
    assert value is getattr(importlib.import_module(f"tactilab.core.{module}"), name)


def test_an_unknown_name_is_an_attribute_error_without_a_warning():
    import tactilab.data_schemas.batch as old

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(AttributeError, match="module 'tactilab.data_schemas.batch' has no attribute 'nothing'"):
            old.nothing  # noqa: B018
        with pytest.raises(AttributeError, match="module 'tactilab.data_schemas' has no attribute 'nothing'"):
            records.nothing  # noqa: B018
