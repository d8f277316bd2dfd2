"""Saving and loading results: a documented ``.npz`` format, written atomically.

Functions
---------
``save(result, path)`` / ``load(path)``
    A :class:`~morphlab.results.result.Result` (a simulation or a static equilibrium path) with
    everything its accessors need: a loaded result gives bitwise the same ``t, q, v, a, lam``
    and the same ``node_positions``, ``stress``, ``point_positions``, ``reference``, ``dof``,
    ``summary`` and (when every time profile of the model could be stored) ``energy``.
``save_arrays(path, arrays, meta)`` / ``load_arrays(path)``
    A plain dict of arrays with a JSON-serializable dict of metadata (sensitivity results,
    studies, anything else).
``read_metadata(path)``
    The JSON metadata of either kind of file, without loading the arrays.

File format (``format_version`` 2)
----------------------------------
A file is an uncompressed ZIP archive of ``.npy`` members, i.e. a NumPy ``.npz`` file: it opens
with ``numpy.load(path, allow_pickle=False)`` and holds no pickled Python objects. The member
``metadata`` is a 0-d unicode array with one JSON document::

    {"format": "morphlab-result" or "morphlab-arrays",
     "format_version": 2,
     "morphlab_version": "0.1.0",
     ...}

JSON numbers are written by Python's ``json`` (shortest repr that reads back to the same
float, ``NaN``/``Infinity`` for non-finite values). A value that JSON cannot hold exactly -- an
array, a complex number -- is stored as a member of its own and referenced from the metadata
by ``{"$array": "<member name>"}`` (``"scalar": true`` when it was a scalar); slices are
``{"$slice": [start, stop, step]}``.

Every file lists its array members in ``"members"`` (sorted), so a damaged directory that
hides members is found.

``"morphlab-arrays"`` files add ``"meta"`` (the caller's dict) and ``"arrays"`` (the member
names); every other member is one array of the caller's dict under its own key.

``"morphlab-result"`` files add:

``"model"``
    The model's name.
``"settings"``
    ``{"class": "Settings", "fields": dataclasses.asdict(result.settings)}`` (solver settings:
    ``t_end, dt, rho_inf, tol, max_iter, stabilization, ...``).
``"result"``
    Every field of the Result that is not an array (``status, message, n_factorizations,
    wall_time, scale, newton_history``); the array fields are members ``result/<field>``
    (``result/t`` (n_t,), ``result/q``, ``result/v``, ``result/a`` (n_t, n_dof),
    ``result/lam`` (n_t, n_con), ``result/newton_iterations``,
    ``result/constraint_violation``, ``result/velocity_violation`` (n_t,)).
``"system"``
    The compiled :class:`~morphlab.compile.System` without its model: ``dtype``, ``n_dof``,
    ``n_con``, ``length_scale``, ``dof_names``, ``con_names``, ``con_joint``; ``kinds`` (the
    kinds of item the model has) and ``names`` (each kind's item names); ``bodies`` (per
    body: ``name, index, kind, elements`` and its arrays ``ref`` (3,), ``angle0``,
    ``node_dofs`` (n_node, 3), ``X`` (n_node, 2) as members ``system/bodies/<i>/<field>``);
    ``time_profiles`` (per kind, ``[item, profile]`` pairs). Each kind's table is written
    field by field as :mod:`morphlab.kernels.schema` declares it, members
    ``system/arrays/<kind>/<field>`` (and ``system/arrays/gravity``), its time constants
    ``system/time_base/<kind>``; every other array of the System (``q0, v0, indices, indptr,
    con_sign, ...``) is a member ``system/<field>``. Files of format version 1 (the earlier
    layout of the system) are refused with a :class:`~morphlab.errors.FormatError`.
``"bodies"``
    The bodies of the model (not its joints and loads, which live in the System arrays):
    ``{"kind": "rigid" | "beam", "name", <constructor parameters>}``, numbers inline or as
    members ``model/bodies/<i>/<parameter>``; ``"gravity"`` likewise.
``"units"``
    The unit system the model declares (``model.units``, :mod:`morphlab.model.units`): its
    name (``"mm-t-s"``, ``"nondimensional"``), its fields for a user's own
    :class:`~morphlab.model.units.UnitSystem`, or null (none declared; files without the key
    read the same).

A time profile is ``{"$profile": "<class name>", "fields": {...}}`` for the profiles of
:mod:`morphlab.model.profiles` built from numbers (``Constant, Ramp, SmoothStep, Sine, Linear,
Polynomial``) and from such profiles (``Sum, Scaled, Product, Integral``: their profile fields
nested the same way). A user callable (``Custom`` or a user subclass) cannot be stored
without pickling code: it is written as ``{"$profile": null, "repr": "..."}`` and loads as an
:class:`UnsavedProfile`, which raises :class:`~morphlab.errors.FormatError` when evaluated, so
everything except ``energy`` and ``System.time_arrays`` still works.

``"morphlab-sensitivity"`` files (a :class:`~morphlab.sensitivity.SensitivityResult`) are
result files of its primal ``result`` plus ``"sensitivity"``: ``method``, ``variables``,
``design`` (the nominal ``p0``), ``values``, ``gradients``, ``timing``, ``stats`` and
``state`` (the kept sensitivity histories, members ``sensitivity/state/<name>``, e.g.
``(n_t, n_dof, n_x)``). A loaded one has no perturbed histories: ``derivative()`` needs the
live object.

On load, the model is rebuilt with its bodies only (for the accessors that look bodies up by
name); to simulate again, build the model anew.

Verified reading
----------------
Every member read is read to its end, so its CRC-32 is checked, and its ``.npy`` header must
describe exactly its bytes (:mod:`morphlab.io.container`); a damaged, foreign or incomplete file
(missing members or metadata keys included) raises :class:`~morphlab.errors.FormatError`
naming the file.

Atomic writes
-------------
The archive is written to a temporary file in the destination folder, flushed to disk, and
moved over ``path`` with :func:`os.replace` (atomic on POSIX and Windows within one file
system). If anything fails while writing, the temporary file is removed and an existing file
at ``path`` is left untouched: there is never a partial file under the final name.

Modules
-------
:mod:`~morphlab.io.container` the ``.npz`` container (atomic writes, verified reads);
:mod:`~morphlab.io.encoding` values and time profiles in the metadata;
:mod:`~morphlab.io.files` the metadata member, the format version, plain-array files;
:mod:`~morphlab.io.system` the System and the model's bodies of a result file;
:mod:`~morphlab.io.results` results and sensitivity results (:func:`save`, :func:`load`).
"""

from .encoding import UnsavedProfile
from .files import (
    ARRAYS_FORMAT,
    FORMAT_VERSION,
    METADATA,
    RESULT_FORMAT,
    SENSITIVITY_FORMAT,
    load_arrays,
    read_metadata,
    save_arrays,
)
from .results import load, save

__all__ = [
    "ARRAYS_FORMAT", "FORMAT_VERSION", "METADATA", "RESULT_FORMAT", "SENSITIVITY_FORMAT",
    "UnsavedProfile", "load", "load_arrays", "read_metadata", "save", "save_arrays",
]
