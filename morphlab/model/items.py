"""The common base of everything a :class:`~morphlab.model.Model` holds, and the registry of
the model's lists.

Every kind of item (a body, joint, load or force element) is a class derived from
:class:`Item` that says which list of the model it goes to (:attr:`Item.collection`, e.g.
``"joints"``), among which names it must be unique (:attr:`Item.namespace`) and how it is
called in messages (:attr:`Item.label`), and that validates itself against the model
(:meth:`Item.check`). :meth:`Model.add <morphlab.model.Model.add>` is the one path by which
items enter a model; a new kind of item needs no change to the model: its class registers its
list here when it is defined, and every new :class:`~morphlab.model.Model` has that list.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

if TYPE_CHECKING:
    from .model import Model

#: The model's lists of items: attribute name -> the namespace of their names.
COLLECTIONS: dict[str, str] = {}

#: Per namespace: the word for one item in messages, and what a message about a taken name adds.
NAMESPACES: dict[str, tuple[str, str]] = {
    "bodies": ("body", " ('ground' is reserved); body names must be unique"),
    "joints": ("joint", ""),
    "loads": ("load", " (loads and force elements share one set of names)"),
}


class Item:
    """Base of bodies, joints, loads and force elements.

    Class attributes of each kind, given as keywords of the class statement (or assigned in
    its body):

    collection : str
        The list of the model the item is added to (``"bodies"``, ``"joints"``, ``"forces"``,
        ``"torques"``, ``"springs"``, ``"line_loads"``, ...).
    namespace : str
        Names are unique among the items of one namespace (a key of :data:`NAMESPACES`).
    label : str
        The kind's name in messages (``"revolute"``, ``"rotational spring"``).
    prefix : str
        Default names are the prefix followed by the length of the item's list.
    """

    collection: ClassVar[str] = ""
    namespace: ClassVar[str] = ""
    label: ClassVar[str] = "item"
    prefix: ClassVar[str] = "item"

    name: str | None
    _model: Model | None = None  # set by Model.add: an item belongs to one model

    def __init_subclass__(cls, *, collection: str | None = None, namespace: str | None = None,
                          label: str | None = None, prefix: str | None = None, **kwargs):
        """Take the kind's attributes from the class statement, e.g.
        ``class Torque(Load, collection="torques", label="torque")``; the prefix defaults to
        the label with underscores for spaces. Attributes not given are inherited."""
        super().__init_subclass__(**kwargs)
        for key, value in (("collection", collection), ("namespace", namespace),
                           ("label", label)):
            if value is not None:
                setattr(cls, key, value)
        if prefix is not None or label is not None:
            cls.prefix = prefix if prefix is not None else label.replace(" ", "_")
        if cls.collection:
            if cls.namespace not in NAMESPACES:
                raise TypeError(f"{cls.__name__}: namespace must be one of "
                                f"{sorted(NAMESPACES)}, got {cls.namespace!r}")
            COLLECTIONS.setdefault(cls.collection, cls.namespace)

    @property
    def owner(self) -> str:
        """How messages name the item: its kind and name, e.g. ``"revolute 'A'"``."""
        return f"{self.label} {self.name!r}"

    def check(self, model: Model) -> None:
        """Validate the item against ``model`` before it is added, and bring its fields to
        their canonical form: bodies given by name become the model's bodies, numbers NumPy
        values of double precision, points on a beam that beam's node.

        Raises
        ------
        ModelError
            Naming the item (:attr:`owner`) and what would be valid.
        """
