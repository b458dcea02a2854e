"""Recording: shapes, tidy DataFrame round-trip, unit conversion at the edge, every rule."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from tactilab.data_schemas.recording import TIDY_COLUMNS, Recording
from tactilab.data_schemas.sensors import SensorArray


@pytest.fixture
def recording(rng) -> Recording:
    return Recording(values=rng.normal(size=(7, 3, 2)) * 1e3, sampling_rate_hz=500.0,
                     sensor_ids=("a", "b", "c"), components=("zz", "zx"), start_time_s=0.25,
                     description="synthetic")


def test_times_and_series(recording):
    assert (recording.n_times, recording.n_sensors, recording.n_components) == (7, 3, 2)
    assert recording.unit == "Pa"  # filled in from the quantity
    np.testing.assert_allclose(recording.times_s, 0.25 + np.arange(7) / 500.0)
    assert recording.duration_s == pytest.approx(7 / 500.0)
    np.testing.assert_array_equal(recording.series("b", "zx"), recording.values[:, 1, 1])


def test_tidy_frame_layout(recording):
    df = recording.to_dataframe()
    assert tuple(df.columns) == TIDY_COLUMNS and len(df) == 7 * 3 * 2
    row = df.iloc[2 * 3 * 2 + 1 * 2 + 1]  # time index 2, sensor "b", component "zx"
    assert (row.sensor, row.component) == ("b", "zx")
    assert row.time_s == pytest.approx(0.25 + 2 / 500.0)
    assert row.value == recording.values[2, 1, 1]
    assert df.attrs["unit"] == "Pa" and df.attrs["sampling_rate_hz"] == 500.0


def test_dataframe_round_trip_is_exact_even_shuffled(recording, rng):
    df = recording.to_dataframe()
    assert Recording.from_dataframe(df) == recording
    shuffled = df.sample(frac=1.0, random_state=np.random.RandomState(rng.integers(2**31)))
    shuffled.attrs = dict(df.attrs)
    assert Recording.from_dataframe(shuffled) == recording
    # without attrs the axes follow the order of first appearance; the given order restores them
    shuffled.attrs.clear()
    back = Recording.from_dataframe(shuffled, sensor_ids=["a", "b", "c"], components=["zz", "zx"],
                                    description="synthetic")
    assert back == recording
    with pytest.raises(ValueError, match=r"the sensor column holds \['a', 'b', 'c'\] but the sensor order given is \['a', 'b'\]"):
        Recording.from_dataframe(shuffled, sensor_ids=["a", "b"])


def test_dataframe_without_attrs_infers_rate_and_start(recording):
    df = recording.to_dataframe()
    df.attrs.clear()
    back = Recording.from_dataframe(df, description="synthetic")
    assert back == recording  # 500 Hz recovered exactly after rounding to 10 digits


def test_dataframe_in_kpa_is_converted_once(recording):
    df = recording.to_dataframe()
    df["value"] = df["value"] / 1e3
    back = Recording.from_dataframe(df, unit="kPa")
    np.testing.assert_allclose(back.values, recording.values, rtol=1e-15)
    assert back.unit == "Pa"


def test_json_round_trip_is_exact(recording, tmp_path):
    assert Recording.from_json(recording.to_json()) == recording
    assert Recording.load(recording.save(tmp_path / "r.json")) == recording


def test_from_sensors_and_matching():
    sensors = SensorArray.grid(2, 1, 1e-3, 1e-3, components=["xx", "zx"], quantity="strain")
    r = Recording.from_sensors(sensors, np.zeros((4, 2, 2)), sampling_rate_hz=1e3)
    assert r.unit == "strain" and r.sensor_ids == ("s0", "s1")
    r.check_matches(sensors)
    with pytest.raises(ValueError, match=r"recording components \('xx', 'zx'\) does not match the sensor array's \('xx',\)"):
        r.check_matches(sensors.replace(components=["xx"]))
    with pytest.raises(ValueError, match="recording quantity 'strain' does not match"):
        r.check_matches(sensors.replace(quantity="stress"))
    with pytest.raises(ValueError, match="recording sensor_ids"):
        r.check_matches(sensors.replace(sensor_ids=("p", "q")))
    with pytest.raises(ValueError, match=r"values has shape \(4, 3, 2\) .* but sensor_ids has 2 entries"):
        Recording.from_sensors(sensors, np.zeros((4, 3, 2)), sampling_rate_hz=1e3)


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        (dict(values=np.zeros((5, 2))), r"values must have 3 dimension\(s\).*got shape \(5, 2\)"),
        (dict(values=np.full((5, 2, 1), np.inf)), r"values must be finite everywhere, got inf"),
        (dict(sensor_ids=("a",)), r"values has shape \(5, 2, 1\) \(n_times, n_sensors, n_components\) but sensor_ids has 1 entries"),
        (dict(components=("zz", "zx")), r"values has shape \(5, 2, 1\) .* but components has 2 entries"),
        (dict(components=("qq",)), r"components: unknown component 'qq'; valid names are"),
        (dict(sensor_ids=("a", "a")), r"sensor_ids must be unique"),
        (dict(sampling_rate_hz=0.0), r"sampling_rate_hz must be > 0"),
        (dict(sampling_rate_hz=np.nan), r"sampling_rate_hz must be finite"),
        (dict(start_time_s=np.nan), r"start_time_s must be finite"),
        (dict(unit="kPa"), r"unit must be the SI unit 'Pa' for quantity 'stress', got 'kPa'; convert the values"),
        (dict(unit="furlong"), r"unit: unknown unit 'furlong'"),
        (dict(unit="mm"), r"unit: unit 'mm' measures length, but a pressure is expected"),
        (dict(quantity="strain", unit="Pa"), r"unit 'Pa' is not a unit of strain; strain is dimensionless"),
    ],
)
def test_recording_rules(change, pattern):
    fields = dict(values=np.zeros((5, 2, 1)), sampling_rate_hz=100.0, sensor_ids=("a", "b"), components=("zz",))
    fields.update(change)
    with pytest.raises(ValueError, match=pattern):
        Recording(**fields)


def test_recordings_accept_the_shear_aliases_in_records_and_tables():
    """'xz' is 'zx' in a recording too (tactilab.core.rules.components), also in a table's component column."""
    rec = Recording(values=np.arange(4.0).reshape(2, 1, 2), sampling_rate_hz=100.0, sensor_ids=("a",),
                    components=("zz", "xz"))
    assert rec.components == ("zz", "zx")
    df = rec.to_dataframe()
    df["component"] = df["component"].replace({"zx": "xz"})
    back = Recording.from_dataframe(df, sampling_rate_hz=100.0, components=("zz", "xz"))
    assert back.components == ("zz", "zx")
    np.testing.assert_array_equal(back.values, rec.values)


def test_series_rules(recording):
    with pytest.raises(ValueError, match=r"sensor 'z' is not in this recording; use one of \['a', 'b', 'c'\]"):
        recording.series("z", "zz")
    with pytest.raises(ValueError, match=r"component 'xx' is not in this recording"):
        recording.series("a", "xx")


def test_from_dataframe_rules(recording):
    good = recording.to_dataframe()

    def bare():
        df = good.copy()
        df.attrs.clear()
        return df

    with pytest.raises(ValueError, match=r"df lacks the columns \['component'\]"):
        Recording.from_dataframe(good.drop(columns="component"))
    with pytest.raises(ValueError, match="df has no rows"):
        Recording.from_dataframe(good.iloc[:0])
    with pytest.raises(ValueError, match="quantity must be 'stress' or 'strain', got 'force'"):
        Recording.from_dataframe(good, quantity="force")
    with pytest.raises(ValueError, match="unit: unknown unit 'bar'"):
        Recording.from_dataframe(good, unit="bar")
    nan_time = bare()
    nan_time.loc[0, "time_s"] = np.nan
    with pytest.raises(ValueError, match="time_s must be finite"):
        Recording.from_dataframe(nan_time)
    one_time = bare()[lambda d: d.time_s == d.time_s.min()]
    with pytest.raises(ValueError, match="time_s has a single value, so the sampling rate is unknown"):
        Recording.from_dataframe(one_time)
    assert Recording.from_dataframe(one_time, sampling_rate_hz=500.0).n_times == 1
    with pytest.raises(ValueError, match=r"sampling_rate_hz must be > 0, got -5.0"):
        Recording.from_dataframe(good, sampling_rate_hz=-5.0)
    jitter = bare()
    jitter.loc[jitter.index[-1], "time_s"] += 1e-4
    with pytest.raises(ValueError, match=r"time_s must be uniformly sampled at 500.0 Hz .* resample"):
        Recording.from_dataframe(jitter, sampling_rate_hz=500.0)
    duplicated = pd.concat([good, good.iloc[[3]]])
    duplicated.attrs = dict(good.attrs)
    with pytest.raises(ValueError, match=r"df has 2 rows for time .* sensor 'b', component 'zx'"):
        Recording.from_dataframe(duplicated)
    holed = good.drop(index=3)
    holed.attrs = dict(good.attrs)
    with pytest.raises(ValueError, match=r"df has no row for time .* sensor 'b', component 'zx'"):
        Recording.from_dataframe(holed)
    renamed = good.copy()
    renamed["component"] = renamed["component"].replace({"zx": "shear"})
    with pytest.raises(ValueError, match="component column: unknown component 'shear'"):
        Recording.from_dataframe(renamed)
