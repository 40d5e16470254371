"""What `pmsm2dof drive` decides without a drive: the link URL it accepts, and MDF4 logs read by read_log.

The MDF4 files are written here by asammdf (the library CANape's and INCA's format is read with
elsewhere too), the CSV by pandas; read_log must give the same samples from both.
"""

import numpy as np
import pandas as pd
import pytest

from pmsm2dof.drive.transport import link_url
from pmsm2dof.errors import ConfigError
from pmsm2dof.sim.logs import read_log

asammdf = pytest.importorskip("asammdf")


@pytest.mark.parametrize(
    ("text", "url"),
    [
        ("tcp://127.0.0.1:5555", "tcp://127.0.0.1:5555"),
        ("socket://127.0.0.1:5555", "tcp://127.0.0.1:5555"),
        ("tcp://localhost:1", "tcp://localhost:1"),
        ("tcp://[::1]:65535", "tcp://::1:65535"),
        ("tcp://127.3.4.5:80", "tcp://127.3.4.5:80"),
        ("serial:/dev/pts/3", "/dev/pts/3"),
        ("/dev/ttyUSB0", "/dev/ttyUSB0"),
        ("COM3", "COM3"),
    ],
)
def test_link_urls_accepted(text, url):
    assert link_url(text) == url


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("tcp://192.0.2.1:5555", "this machine"),
        ("tcp://drive.example.org:5555", "this machine"),
        ("tcp://10.0.0.2:5555", "this machine"),
        ("tcp://127.0.0.1:0", "1..65535"),
        ("tcp://127.0.0.1:70000", "1..65535"),
        ("tcp://127.0.0.1", "tcp://HOST:PORT"),
        ("http://127.0.0.1:5555", "tcp://HOST:PORT"),
        ("serial:", "tcp://HOST:PORT"),
    ],
)
def test_link_urls_refused(text, words):
    with pytest.raises(ConfigError) as caught:
        link_url(text)
    assert caught.value.param == "link" and words in str(caught.value)


def test_a_remote_drive_when_allowed():
    assert link_url("tcp://192.0.2.1:5555", allow_remote=True) == "tcp://192.0.2.1:5555"


def test_read_log_reads_mdf4_as_the_same_samples_as_csv(tmp_path):
    rng = np.random.default_rng(7)
    t = np.arange(500) * 5e-4
    speed = np.cumsum(rng.normal(size=500)).astype(np.float32) + np.float32(1000.0)
    iq = rng.normal(size=500).astype(np.float32)
    mdf = asammdf.MDF(version="4.10")
    mdf.append([asammdf.Signal(speed, t, name="speed_rpm", unit="rpm"), asammdf.Signal(iq, t, name="iq_A", unit="A")])
    mdf.save(tmp_path / "log.mf4")
    mdf.close()
    pd.DataFrame({"t_s": t, "speed_rpm": speed.astype(float), "iq_A": iq.astype(float)}).to_csv(
        tmp_path / "log.csv", index=False
    )
    a, b = read_log(tmp_path / "log.mf4"), read_log(tmp_path / "log.csv")
    for name in ("t_s", "speed_rpm", "w_m_radps", "iq_A"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    np.testing.assert_allclose(a.speed_rpm, speed, rtol=1e-15)  # through rad/s and back
    assert a.columns == {"time": "t_s", "speed": "speed_rpm", "iq": "iq_A"}


def test_read_log_refuses_mdf4_groups_on_different_time_bases(tmp_path):
    mdf = asammdf.MDF(version="4.10")
    mdf.append([asammdf.Signal(np.ones(10), np.arange(10) * 1e-3, name="speed_rpm")])
    mdf.append([asammdf.Signal(np.ones(5), np.arange(5) * 2e-3, name="iq_A")])
    mdf.save(tmp_path / "two.mf4")
    mdf.close()
    with pytest.raises(ConfigError, match="one time base"):
        read_log(tmp_path / "two.mf4")


def test_read_log_refuses_a_file_that_is_not_mdf4(tmp_path):
    (tmp_path / "bad.mf4").write_bytes(b"MDF     not really")
    with pytest.raises(ConfigError) as caught:
        read_log(tmp_path / "bad.mf4")
    assert caught.value.param == "log"
