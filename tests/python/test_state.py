"""FMU state: get/set, serialize/deserialize, across instances and processes.

The reference motion is run to t = 0.3 s (both flexible joints are moving, with
stick-slip), the state is saved, and 50 more steps give the continuation A. Every
restore below must reproduce A bit for bit (np.array_equal on all Real and Boolean
outputs after each of the 50 steps).
"""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Error

from helpers import Slave, reference_slave, scratch_dir

K0 = 300  # steps before the snapshot (t = 0.3 s)
N = 50  # steps of the continuation


@pytest.fixture(scope="module")
def snapshot():
    """(instance at t_K0 + N, its saved state at t_K0, the serialized state, continuation A)."""
    slave = reference_slave("origin")
    slave.run_reference(0, K0)
    state = slave.fmu.getFMUstate()
    data = slave.fmu.serializeFMUstate(state)
    a = slave.run_reference(K0, N)
    yield slave, state, data, a
    slave.fmu.freeFMUstate(state)
    slave.free()


def test_continuation_moves(snapshot):
    """The 50-step continuation is not trivial: q[3] changes over it and joint 3
    is slipping at some point (so a wrong restore could not go unnoticed)."""
    slave, _, _, a = snapshot
    names = slave.output_names()
    q3 = a[:, names.index("q[3]")]
    assert q3.max() - q3.min() > 1e-5
    assert np.any(a[:, names.index("stick[3]")] == 0.0)


def test_get_set_state_reproduces_continuation(snapshot):
    """fmi2SetFMUstate with the state got at t_K0 (after the instance went on to
    t_K0 + 50 steps) and the same 50 steps again give outputs identical to A."""
    slave, state, _, a = snapshot
    slave.fmu.setFMUstate(state)
    assert slave.run_reference(K0, N).tobytes() == a.tobytes()


def test_serialize_deserialize_same_instance(snapshot):
    """The serialized state, deserialized into the same instance and set, gives A bit for bit;
    the serialized form of the deserialized state is byte-identical to the original."""
    slave, _, data, a = snapshot
    assert isinstance(data, bytes) and len(data) > 0
    restored = slave.fmu.deSerializeFMUstate(data)
    try:
        assert slave.fmu.serializeFMUstate(restored) == data
        slave.fmu.setFMUstate(restored)
        assert slave.run_reference(K0, N).tobytes() == a.tobytes()
    finally:
        slave.fmu.freeFMUstate(restored)


@pytest.mark.parametrize("initialized", [False, True], ids=["instantiated-only", "initialized-elsewhere"])
def test_deserialize_into_second_instance(snapshot, initialized):
    """A second instance, either just instantiated or initialized and stepped to another
    time (0.1 s), takes the serialized state and continues exactly like A."""
    _, _, data, a = snapshot
    with Slave("second") as other:
        if initialized:
            other.initialize()
            other.run_reference(0, 100)
        st = other.fmu.deSerializeFMUstate(data)
        other.fmu.setFMUstate(st)
        other.fmu.freeFMUstate(st)
        assert other.run_reference(K0, N).tobytes() == a.tobytes()


def _bad_buffers(data: bytes):
    rng = np.random.default_rng(12345)
    flipped = bytearray(data)
    flipped[len(data) // 2] ^= 0x10  # one bit in the middle (a number of the state)
    last = bytearray(data)
    last[-1] ^= 0x01
    return {
        "corrupted-middle-bit": bytes(flipped),
        "corrupted-last-byte": bytes(last),
        "truncated": data[: len(data) - 8],
        "truncated-to-half": data[: len(data) // 2],
        "extended": data + b"\0" * 8,
        "foreign-random": rng.integers(0, 256, len(data), dtype=np.uint8).tobytes(),
        "foreign-short": b"not an FMU state",
        "empty": b"",
    }


def test_bad_serialized_states_are_rejected(snapshot):
    """A corrupted (one bit flipped), truncated, extended, foreign (random bytes) or empty
    buffer is rejected by fmi2DeSerializeFMUstate with fmi2Error (fmpy raises
    FMICallException, status 3), with a logged reason; the instance still works afterwards:
    the good state restores and continues exactly like A."""
    slave, state, data, a = snapshot
    for label, buf in _bad_buffers(data).items():
        slave.log.clear()
        with pytest.raises(FMICallException) as info:
            slave.fmu.deSerializeFMUstate(buf)
        assert info.value.status == fmi2Error, label
        assert slave.log.records, f"{label}: no log message"
        assert any("fmi2DeSerializeFMUstate" in m for m in slave.log.messages()), (label, slave.log.text())
    slave.fmu.setFMUstate(state)
    assert slave.run_reference(K0, N).tobytes() == a.tobytes()


CHILD = r"""
import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from helpers import Slave
data = open(sys.argv[2], "rb").read()
k0, n = int(sys.argv[4]), int(sys.argv[5])
with Slave("child") as s:
    st = s.fmu.deSerializeFMUstate(data)
    s.fmu.setFMUstate(st)
    s.fmu.freeFMUstate(st)
    np.save(sys.argv[3], s.run_reference(k0, n))
"""


def test_deserialize_in_another_process(snapshot):
    """The serialized state written to a file and deserialized by a new Python process
    (its own copy of the library and of the FMU) continues exactly like A."""
    _, _, data, a = snapshot
    d = scratch_dir()
    state_file = d / "state.bin"
    out_file = d / "child.npy"
    state_file.write_bytes(data)
    env = dict(os.environ)
    subprocess.run(
        [sys.executable, "-c", CHILD, str(Path(__file__).parent), str(state_file), str(out_file), str(K0), str(N)],
        check=True,
        env=env,
        timeout=120,
    )
    child = np.load(out_file)
    assert child.tobytes() == a.tobytes()
