"""FMU state: get/set, serialize/deserialize, across instances and processes.

The reference motion is run to t = 0.3 s (both flexible joints are moving, with
stick-slip), the state is saved, and 50 more steps give the continuation A. Every
restore below must reproduce A bit for bit (np.array_equal on all Real and Boolean
outputs after each of the 50 steps).

Every test runs twice: on the reference FMU (id ``reference``) and on the FMU with motor
drives (id ``motor``, models/reference_rrpr_motor.toml, built by motor_fmus.py), there from a
static start with the standard drive of motor_fmus.py: the reference motion on the rigid
joints, the motor torques as ramps whose rates were set through
fmi2SetRealInputDerivatives before the snapshot and are not set again in the continuation
(joint 3's until its end, joint 1's for its first 20 steps), so the state must carry the
motor states, tau_m and its derivatives (format version 3). A state of one FMU is refused by
the other.
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
from motor_fmus import motor_slave, require_motor_fmu, run_motor

K0 = 300  # steps before the snapshot (t = 0.3 s)
N = 50  # steps of the continuation


class Reference:
    """The reference FMU on the reference motion."""

    path = None  # the FMU under test (helpers.fmu_path)

    @staticmethod
    def initialized(name):
        return reference_slave(name)

    @staticmethod
    def instantiated(name):
        return Slave(name)

    @staticmethod
    def run(slave, k0, n):
        return slave.run_reference(k0, n)


class Motor:
    """The motor FMU on the standard drive of motor_fmus.py, from a static start."""

    path = None  # set by the fixture (built on first use)

    @classmethod
    def initialized(cls, name):
        return motor_slave(name, path=cls.path)

    @classmethod
    def instantiated(cls, name):
        return Slave(name, path=cls.path)

    @staticmethod
    def run(slave, k0, n):
        return run_motor(slave, k0, n)


KINDS = {"reference": Reference, "motor": Motor}


@pytest.fixture(scope="module", params=list(KINDS))
def kind(request):
    kind = KINDS[request.param]
    if kind is Motor:
        Motor.path = str(require_motor_fmu())
    return kind


@pytest.fixture(scope="module")
def snapshot(kind):
    """(instance at t_K0 + N, its saved state at t_K0, the serialized state, continuation A, kind)."""
    slave = kind.initialized("origin")
    kind.run(slave, 0, K0)
    state = slave.fmu.getFMUstate()
    data = slave.fmu.serializeFMUstate(state)
    a = kind.run(slave, K0, N)
    yield slave, state, data, a, kind
    slave.fmu.freeFMUstate(state)
    slave.free()


def test_continuation_moves(snapshot):
    """The 50-step continuation is not trivial (so a wrong restore could not go unnoticed).
    Reference: q[3] changes over it and joint 3 is slipping at some point. Motor: rotor 1
    reverses (omega_m[1] changes sign), rotor 3 is stuck at the start and slipping at the end,
    and q[1] changes."""
    slave, _, _, a, kind = snapshot
    names = slave.output_names()
    col = lambda name: a[:, names.index(name)]  # noqa: E731
    if kind is Reference:
        q3 = col("q[3]")
        assert q3.max() - q3.min() > 1e-5
        assert np.any(col("stick[3]") == 0.0)
    else:
        assert col("omega_m[1]").max() > 1.0 and col("omega_m[1]").min() < -1.0
        assert col("stick_m[3]")[0] == 1.0 and col("stick_m[3]")[-1] == 0.0
        assert col("q[1]").max() - col("q[1]").min() > 1e-4


def test_get_set_state_reproduces_continuation(snapshot):
    """fmi2SetFMUstate with the state got at t_K0 (after the instance went on to
    t_K0 + 50 steps) and the same 50 steps again give outputs identical to A."""
    slave, state, _, a, kind = snapshot
    slave.fmu.setFMUstate(state)
    assert kind.run(slave, K0, N).tobytes() == a.tobytes()


def test_serialize_deserialize_same_instance(snapshot):
    """The serialized state, deserialized into the same instance and set, gives A bit for bit;
    the serialized form of the deserialized state is byte-identical to the original."""
    slave, _, data, a, kind = snapshot
    assert isinstance(data, bytes) and len(data) > 0
    restored = slave.fmu.deSerializeFMUstate(data)
    try:
        assert slave.fmu.serializeFMUstate(restored) == data
        slave.fmu.setFMUstate(restored)
        assert kind.run(slave, K0, N).tobytes() == a.tobytes()
    finally:
        slave.fmu.freeFMUstate(restored)


@pytest.mark.parametrize("initialized", [False, True], ids=["instantiated-only", "initialized-elsewhere"])
def test_deserialize_into_second_instance(snapshot, initialized):
    """A second instance, either just instantiated or initialized and stepped to another
    time (0.1 s), takes the serialized state and continues exactly like A."""
    _, _, data, a, kind = snapshot
    with kind.initialized("second") if initialized else kind.instantiated("second") as other:
        if initialized:
            kind.run(other, 0, 100)
        st = other.fmu.deSerializeFMUstate(data)
        other.fmu.setFMUstate(st)
        other.fmu.freeFMUstate(st)
        assert kind.run(other, K0, N).tobytes() == a.tobytes()


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
    slave, state, data, a, kind = snapshot
    for label, buf in _bad_buffers(data).items():
        slave.log.clear()
        with pytest.raises(FMICallException) as info:
            slave.fmu.deSerializeFMUstate(buf)
        assert info.value.status == fmi2Error, label
        assert slave.log.records, f"{label}: no log message"
        assert any("fmi2DeSerializeFMUstate" in m for m in slave.log.messages()), (label, slave.log.text())
    slave.fmu.setFMUstate(state)
    assert kind.run(slave, K0, N).tobytes() == a.tobytes()


def test_state_of_the_other_fmu_is_rejected(snapshot):
    """A state serialized by the other FMU (motor drives or not: another model) is rejected by
    fmi2DeSerializeFMUstate with fmi2Error and a logged reason; the instance still restores
    its own state and continues exactly like A."""
    slave, state, _, a, kind = snapshot
    other = Motor if kind is Reference else Reference
    if other is Motor:
        Motor.path = str(require_motor_fmu())
    with other.initialized("other") as s:
        other.run(s, 0, 5)
        st = s.fmu.getFMUstate()
        foreign = s.fmu.serializeFMUstate(st)
        s.fmu.freeFMUstate(st)
    slave.log.clear()
    with pytest.raises(FMICallException) as info:
        slave.fmu.deSerializeFMUstate(foreign)
    assert info.value.status == fmi2Error
    assert any("fmi2DeSerializeFMUstate" in m for m in slave.log.messages()), slave.log.text()
    slave.fmu.setFMUstate(state)
    assert kind.run(slave, K0, N).tobytes() == a.tobytes()


CHILD = r"""
import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from helpers import Slave
from motor_fmus import run_motor
data = open(sys.argv[2], "rb").read()
k0, n, kind, path = int(sys.argv[4]), int(sys.argv[5]), sys.argv[6], sys.argv[7]
with Slave("child", path=path or None) as s:
    st = s.fmu.deSerializeFMUstate(data)
    s.fmu.setFMUstate(st)
    s.fmu.freeFMUstate(st)
    np.save(sys.argv[3], run_motor(s, k0, n) if kind == "motor" else s.run_reference(k0, n))
"""


def test_deserialize_in_another_process(snapshot):
    """The serialized state written to a file and deserialized by a new Python process
    (its own copy of the library and of the FMU) continues exactly like A."""
    _, _, data, a, kind = snapshot
    name = next(k for k, v in KINDS.items() if v is kind)
    d = scratch_dir()
    state_file = d / f"state-{name}.bin"
    out_file = d / f"child-{name}.npy"
    state_file.write_bytes(data)
    env = dict(os.environ)
    subprocess.run(
        [
            sys.executable,
            "-c",
            CHILD,
            str(Path(__file__).parent),
            str(state_file),
            str(out_file),
            str(K0),
            str(N),
            name,
            kind.path or "",
        ],
        check=True,
        env=env,
        timeout=120,
    )
    child = np.load(out_file)
    assert child.tobytes() == a.tobytes()
