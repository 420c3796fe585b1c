"""The readers of measurement files: each format written here with its own library, read back into a record."""

import numpy as np
import pytest

from twin.errors import SignalError
from twin.extract.importing import import_record
from twin.extract.signals import check_record

FS = 128.0


@pytest.fixture
def y():
    t = np.arange(1024) / FS
    rng = np.random.default_rng(3)
    base = np.column_stack([np.sin(2 * np.pi * 3 * t), np.cos(2 * np.pi * 7 * t), np.sin(2 * np.pi * 11 * t)])
    return base + 0.05 * rng.standard_normal(base.shape)


def _in_si(ds, y, factors):
    rec = check_record(ds)
    assert rec.fs_hz == pytest.approx(FS)
    expected = (y - y.mean(axis=0)) * factors  # the extraction reads a record about its mean
    np.testing.assert_allclose(rec.y - rec.y.mean(axis=0), expected, rtol=1e-6, atol=1e-9 * np.abs(expected).max())


def test_uff_58_time_responses_give_names_units_quantities_and_rate(tmp_path, y):
    pyuff = pytest.importorskip("pyuff")
    path = tmp_path / "test.uff"
    uff = pyuff.UFF(str(path))
    kinds = [("UGB_x", "um", 8), ("UGB_y", "mm/s", 11), ("HEAD_x", "g", 12)]
    for k, (name, units, code) in enumerate(kinds):
        uff.write_sets(
            pyuff.prepare_58(
                func_type=1,
                rsp_node=k + 1,
                rsp_dir=1,
                ref_node=0,
                ref_dir=0,
                abscissa_spacing=1,
                rsp_ent_name=name,
                data=y[:, k],
                x=np.arange(len(y)) / FS,
                abscissa_min=0.0,
                abscissa_inc=1 / FS,
                abscissa_spec_data_type=17,
                ordinate_spec_data_type=code,
                orddenom_spec_data_type=0,
                z_axis_spec_data_type=0,
                ordinate_axis_units_lab=units,
                id4="2026-05-01T06:00:00Z",
            ),
            mode="add",
        )
    ds = import_record(path)
    assert ds["channel"].values.tolist() == ["UGB_x", "UGB_y", "HEAD_x"]
    assert ds["quantity"].values.tolist() == ["displacement", "velocity", "acceleration"]
    assert ds.attrs["start_time"] == "2026-05-01T06:00:00Z"
    _in_si(ds, y, [1e-6, 1e-3, 9.80665])


def test_uff_without_time_responses_is_refused_by_name(tmp_path):
    pyuff = pytest.importorskip("pyuff")
    path = tmp_path / "geometry.uff"
    pyuff.UFF(str(path)).write_sets(
        pyuff.prepare_15(node_nums=[1, 2], x=[0.0, 1.0], y=[0.0, 0.0], z=[0.0, 0.0]), mode="add"
    )
    with pytest.raises(SignalError, match=r"geometry.uff: no time response \(dataset 58"):
        import_record(path)


def test_tdms_channels_with_their_properties(tmp_path, y):
    nptdms = pytest.importorskip("nptdms")
    path = tmp_path / "run.tdms"
    start = np.datetime64("2026-05-01T06:00:00")
    channels = [
        nptdms.ChannelObject(
            "probes", name, y[:, k], properties={"unit_string": units, "wf_increment": 1 / FS, "wf_start_time": start}
        )
        for k, (name, units) in enumerate([("UGB_x", "um"), ("UGB_y", "um"), ("HEAD_x", "m/s^2")])
    ]
    with nptdms.TdmsWriter(str(path)) as writer:
        writer.write_segment(channels)
    ds = import_record(path)
    assert ds["channel"].values.tolist() == ["UGB_x", "UGB_y", "HEAD_x"]
    assert ds["quantity"].values.tolist() == ["displacement", "displacement", "acceleration"]
    assert ds.attrs["start_time"].startswith("2026-05-01T06:00:00")
    _in_si(ds, y, [1e-6, 1e-6, 1.0])


def test_tdms_channels_of_different_lengths_are_refused(tmp_path, y):
    nptdms = pytest.importorskip("nptdms")
    path = tmp_path / "bad.tdms"
    with nptdms.TdmsWriter(str(path)) as writer:
        writer.write_segment([nptdms.ChannelObject("g", "A", y[:, 0]), nptdms.ChannelObject("g", "B", y[:10, 1])])
    with pytest.raises(SignalError, match=r"bad.tdms: its channels differ in length \(\[10, 1024\]"):
        import_record(path, units="um", fs_hz=FS)


def test_mat_with_a_data_matrix_names_units_and_rate(tmp_path, y):
    from scipy.io import savemat

    path = tmp_path / "test.mat"
    savemat(path, {"data": y.T, "fs": FS, "channels": ["UGB_x", "UGB_y", "LGB_x"], "units": ["mil", "mil", "mil"]})
    ds = import_record(path)  # samples along the longer axis: the matrix was saved channel x time
    assert ds["channel"].values.tolist() == ["UGB_x", "UGB_y", "LGB_x"]
    _in_si(ds, y, 25.4e-6)


def test_mat_with_one_vector_per_channel_and_a_time_vector(tmp_path, y):
    from scipy.io import savemat

    path = tmp_path / "vectors.mat"
    savemat(path, {"t": np.arange(len(y)) / FS, "A": y[:, 0], "B": y[:, 1]})
    ds = import_record(path, units="um")
    assert ds["channel"].values.tolist() == ["A", "B"]
    _in_si(ds, y[:, :2], 1e-6)
    with pytest.raises(SignalError, match="vectors.mat: channel 'A' has no units"):
        import_record(path)


def test_mat_v73_is_read_as_hdf5(tmp_path, y):
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "v73.mat"
    with h5py.File(path, "w", userblock_size=512) as f:  # MATLAB v7.3: HDF5 after a 512-byte header,
        f["data"] = y.T  # arrays stored transposed (column-major)
        f["fs"] = np.array([[FS]])
    with open(path, "r+b") as f:
        f.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Tue Dec  1 12:00:00 2026 HDF5 schema 1.00 .")
        f.seek(124)
        f.write(b"\x00\x02IM")
    ds = import_record(path, units="um", channels=["UGB_x", "UGB_y", "LGB_x"])
    _in_si(ds, y, 1e-6)


def test_hdf5_with_one_dataset_per_channel_and_units_attributes(tmp_path, y):
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "probes.h5"
    with h5py.File(path, "w") as f:
        group = f.create_group("probes", track_order=True)
        f.attrs["sampling_rate"] = FS
        f.attrs["start_time"] = "2026-05-01T06:00:00Z"
        for k, (name, units) in enumerate([("UGB_x", "um"), ("UGB_y", "in/s"), ("HEAD_x", "g")]):
            group.create_dataset(name, data=y[:, k]).attrs["units"] = units
    ds = import_record(path)
    assert ds["channel"].values.tolist() == ["UGB_x", "UGB_y", "HEAD_x"]
    assert ds["quantity"].values.tolist() == ["displacement", "velocity", "acceleration"]
    assert ds.attrs["start_time"] == "2026-05-01T06:00:00Z"
    _in_si(ds, y, [1e-6, 0.0254, 9.80665])


def test_hdf5_problems_name_the_file(tmp_path, y):
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "two.h5"
    with h5py.File(path, "w") as f:
        f["a"], f["b"] = y, y
    with pytest.raises(SignalError, match=r"two.h5: several 2-D arrays \(a, b\) and none named data"):
        import_record(path)
    broken = tmp_path / "broken.h5"
    broken.write_bytes(b"not hdf5 at all")
    with pytest.raises(SignalError, match="broken.h5: not a readable HDF5 file"):
        import_record(broken)
    with h5py.File(path, "w") as f:
        f["data"] = y
        f.attrs["fs"] = -3.0
    with pytest.raises(SignalError, match="two.h5: its sampling rate is -3 Hz"):
        import_record(path, units="um")
