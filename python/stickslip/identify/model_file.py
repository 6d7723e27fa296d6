"""The identified model written back (issue 42, item 4): the FMU's model with identified link
inertias π and tunable parameters (friction, drives, rotors) as a model file, and for a URDF arm
a URDF, from which ``bash scripts/build_fmu.sh --model <toml>`` builds the identified FMU and
which ``stickslip simulate`` and ``stickslip fit`` then use.

The engine writes them (its export ``stickslip_write_model``, called with ctypes on the FMU's
``resources/model.toml``, as :mod:`stickslip.fit.idim` calls ``stickslip_inverse_dynamics``;
src/model/writer.rs says how): every value the model holds, in its shortest round-trip form, the
links' inertial data in the model file's own frames (a Denavit-Hartenberg file: the study's
frame i; a URDF: each moving link's ``<inertial>``, its body with the links the reader merges
into it, whose own ``<inertial>`` elements are removed), the rest of the URDF byte for byte, and a
header saying what changed. The engine reads the written files back to the same model before it
hands them over.

π is the 10n standard parameters in the order and frames of
:func:`stickslip.fit.regressor.joint_torque_regressor`'s π (per link ``m, mc_x, mc_y, mc_z, I_xx,
I_xy, I_yy, I_xz, I_yz, I_zz`` in the engine's link frame, the inertia about its origin); a link
that is not physically consistent (mass ≤ 0, the inertia about the centre of mass not positive
semidefinite or violating the triangle inequality) is refused with its name.
"""

from __future__ import annotations

import ctypes
import functools
from pathlib import Path

import numpy as np

from ..fit.idim import InverseDynamicsError, _model_source, export, library_path

EXPORT = "stickslip_write_model"  # the FMU library's function beyond FMI 2.0


@functools.cache
def _engine(path: str):
    """The export of the library at ``path``, with its C signature."""
    size = ctypes.c_size_t
    argtypes = [
        ctypes.c_char_p,  # model: resources/model.toml
        ctypes.c_char_p,  # urdf: the URDF it names, or NULL
        ctypes.POINTER(ctypes.c_char_p),  # settings "mu_k[1]=0.03", ...
        size,
        ctypes.POINTER(ctypes.c_double),  # parameters: π (10n), or NULL with 0 to keep the links
        size,
        ctypes.c_char_p,  # urdf_file_name: the written model file's `urdf = "..."`
        ctypes.c_char_p,  # toml: the written model file
        size,
        ctypes.c_char_p,  # urdf_out: the written URDF
        size,
        ctypes.POINTER(size),  # toml_needed
        ctypes.POINTER(size),  # urdf_needed
        ctypes.c_char_p,  # message buffer
        size,
    ]
    return export(path, EXPORT, argtypes, "the engine wrote model files")


def model_texts(unzipdir, pi=None, settings=(), urdf_file_name: str = "identified.urdf") -> tuple:
    """(model file text, URDF text or None) of the unpacked FMU ``unzipdir``'s model with the
    links' standard parameters ``pi`` (10n values; None keeps the links) and ``settings`` (tunable
    parameters by FMU name, "mu_k[1]=0.03") applied, the model file naming its URDF
    ``urdf_file_name``; by the engine in the FMU's own binary. Raises
    :class:`~stickslip.fit.idim.StageUnavailable` where the binary cannot do it and
    :class:`~stickslip.fit.idim.InverseDynamicsError` with the engine's reason where it refuses
    the input (a setting, π of the wrong length or a physically impossible link, named)."""
    engine = _engine(str(library_path(unzipdir)))
    text, urdf = _model_source(unzipdir)
    encoded = [str(s).encode() for s in settings]
    if pi is None:
        parameters, pointer = np.zeros(0), None
    else:
        parameters = np.ascontiguousarray(pi, dtype=np.float64).ravel()
        pointer = parameters.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
    message = ctypes.create_string_buffer(1024)
    toml_needed, urdf_needed = ctypes.c_size_t(0), ctypes.c_size_t(0)
    # The first call with no room asks for the sizes (status 2), the second writes.
    toml_out, urdf_out = ctypes.create_string_buffer(0), ctypes.create_string_buffer(0)
    for _ in range(2):
        status = engine(
            text.encode(),
            urdf.encode() if urdf is not None else None,
            (ctypes.c_char_p * max(1, len(encoded)))(*encoded),
            len(encoded),
            pointer,
            parameters.size,
            urdf_file_name.encode(),
            toml_out,
            len(toml_out),
            urdf_out,
            len(urdf_out),
            ctypes.byref(toml_needed),
            ctypes.byref(urdf_needed),
            message,
            len(message),
        )
        if status != 2:
            break
        toml_out = ctypes.create_string_buffer(toml_needed.value)
        urdf_out = ctypes.create_string_buffer(urdf_needed.value)
    if status != 0:
        raise InverseDynamicsError(message.value.decode(errors="replace") or f"{EXPORT} returned {status}")
    return toml_out.value.decode(), urdf_out.value.decode() if urdf_needed.value else None


def write_model(unzipdir, out_dir, pi=None, settings=(), name: str = "identified") -> tuple:
    """Writes the unpacked FMU ``unzipdir``'s model with the links' standard parameters ``pi``
    (10n values; None keeps the links) and ``settings`` (tunable parameters by FMU name,
    "mu_k[1]=0.03") into ``out_dir`` as ``<name>.toml``, and for a URDF arm ``<name>.urdf``
    beside it (the model file names it); returns (toml path, urdf path or None). Errors as
    :func:`model_texts`; ValueError for a ``name`` that is not a plain file name."""
    if not name or name in (".", "..") or Path(name).name != name or "\\" in name:
        raise ValueError(f"name {name!r} must be a plain file name (the files are <name>.toml and <name>.urdf)")
    toml, urdf = model_texts(unzipdir, pi, settings, urdf_file_name=f"{name}.urdf")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    toml_path = out / f"{name}.toml"
    toml_path.write_bytes(toml.encode())  # byte for byte, no newline translation
    if urdf is None:
        return toml_path, None
    urdf_path = out / f"{name}.urdf"
    urdf_path.write_bytes(urdf.encode())
    return toml_path, urdf_path
