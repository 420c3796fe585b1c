"""Measurement files into signals.nc: names, units, quantities and time from the file, every problem named."""

import re

import numpy as np
import pytest

from twin.errors import SignalError
from twin.extract.importing import import_record, quantity_of
from twin.extract.signals import check_record


def _write(tmp_path, name, header, rows, comments=""):
    path = tmp_path / name
    path.write_text(comments + header + "\n" + "\n".join(rows) + "\n")
    return path


@pytest.fixture
def samples():
    t = np.arange(2000) / 100.0
    rng = np.random.default_rng(0)
    return t, np.column_stack([np.sin(2 * np.pi * 3 * t), np.cos(2 * np.pi * 5 * t)]) + 0.1 * rng.standard_normal(
        (2000, 2)
    )


def test_a_csv_with_time_and_units_in_its_header_is_a_record_in_si(tmp_path, samples):
    t, y = samples
    path = _write(
        tmp_path,
        "probes.csv",
        "time [ms],UGB_x [um],HEAD_x [g]",
        [f"{1000 * a:.3f},{b:.6f},{c:.6f}" for a, b, c in zip(t, *y.T)],
    )
    ds = import_record(path)
    assert ds["channel"].values.tolist() == ["UGB_x", "HEAD_x"] and ds.attrs["sampling_rate"] == pytest.approx(100.0)
    assert ds["quantity"].values.tolist() == ["displacement", "acceleration"]
    rec = check_record(ds)
    np.testing.assert_allclose(rec.y.std(axis=0), y.std(axis=0) * [1e-6, 9.80665], rtol=1e-5)


def test_a_text_table_with_the_rate_in_a_comment_and_the_units_given(tmp_path, samples):
    _, y = samples
    path = _write(tmp_path, "probes.txt", "A B", [f"{b:.6f} {c:.6f}" for b, c in y], "# sampling_rate: 100\n")
    ds = import_record(path, units={"A": "mil", "B": "mm/s"}, channels=["UGB_x", "UGB_y"])
    assert ds["quantity"].values.tolist() == ["displacement", "velocity"] and ds["units"].values.tolist() == [
        "mil",
        "mm/s",
    ]
    assert ds["channel"].values.tolist() == ["UGB_x", "UGB_y"] and ds.attrs["sampling_rate"] == 100.0


@pytest.mark.parametrize(
    "header, rows, kwargs, message",
    [
        ("A B", ["1 2", "3 4", "5 6"], {"fs_hz": 10.0}, "channel 'A' has no units"),
        ("A [um],B [um]", ["1,2", "3,4", "5,6"], {}, "no time column and no sampling rate: give the rate"),
        ("A [um],B [um]", ["1,2", "3,x", "5,6"], {"fs_hz": 10.0}, "row 3, column 'B [um]': 'x' is not a number"),
        ("A [um],B [um]", ["1,2", "3", "5,6"], {"fs_hz": 10.0}, "row 3 has 1 values, the header 2 columns"),
        ("1,2", ["1,2", "3,4"], {"fs_hz": 10.0}, "the first line must name the columns"),
        ("A [um],B [N]", ["1,2", "3,4", "5,6"], {"fs_hz": 10.0}, "units 'N' are not of a displacement"),
        (
            "A [um],B [um]",
            ["1,2", "3,4", "5,6"],
            {"fs_hz": 10.0, "quantities": {"B": "velocity"}},
            "channel 'B': units 'um' are not units of velocity",
        ),
        (
            "A [um],B [um]",
            ["1,2", "3,4", "5,6"],
            {"fs_hz": 10.0, "units": {"C": "um"}},
            "units for 'C', which the file",
        ),
        ("time [s],A [um]", ["0,1", "0.1,2", "0.05,3"], {}, "the time does not increase at sample 2"),
    ],
)
def test_every_problem_names_the_file_and_where(tmp_path, header, rows, kwargs, message):
    path = _write(tmp_path, "bad.csv", header, rows)
    with pytest.raises(SignalError, match=re.escape(message)):
        import_record(path, **kwargs)


def test_a_rate_given_twice_must_agree_and_unknown_formats_are_named(tmp_path):
    path = _write(tmp_path, "p.txt", "A [um] B [um]".replace("] ", "],"), ["1,2", "3,4", "5,6"], "# fs: 10\n")
    assert import_record(path, fs_hz=10.0).attrs["sampling_rate"] == 10.0
    with pytest.raises(SignalError, match="the file says 10 Hz, --fs 20 Hz"):
        import_record(path, fs_hz=20.0)
    other = tmp_path / "p.xlsx"
    other.write_bytes(b"PK")
    with pytest.raises(SignalError, match=r"no reader for '.xlsx' files \(twin reads: .csv, .dat, .h5, "):
        import_record(other)


def test_units_tell_the_quantity():
    assert [quantity_of(u, "A") for u in ("mm", "in/s", "m/s^2")] == ["displacement", "velocity", "acceleration"]
