"""A warning for a program compiled again only because a function is a new object.

JAX compiles one program per function *object* it is given as a static argument
(``simulate``'s ``u`` and ``generalized_force``, a linkage's hooks): a lambda or a
closure made anew for every call has the same code each time but is a new object,
so every call traces and compiles the whole program again (seconds each) where one
compiled program could serve them all. :func:`note_function` remembers the last
function object seen for each code object and warns, once per code object, when
another object with the same code arrives.
"""

import types
import warnings
import weakref


class RecompilationWarning(UserWarning):
    """A program was compiled again for a new function object with the same code."""


_LAST: dict[types.CodeType, weakref.ref] = {}
_WARNED: set[types.CodeType] = set()


def note_function(fn, what: str, caller: str) -> None:
    """Warn when ``fn`` is a new object with the code of an earlier ``fn``.

    Args:
        fn: the function given (anything without ``__code__``, e.g. an
            ``equinox.Partial``, is skipped: it is compared by its contents).
        what: the argument's name, for the message (e.g. ``"u"``).
        caller: the sorojax function called (e.g. ``"simulate"``).
    """
    code = getattr(fn, "__code__", None)
    if not isinstance(code, types.CodeType):
        return
    try:
        ref = weakref.ref(fn)
    except TypeError:  # an object that takes no weak references
        return
    last = _LAST.get(code)
    _LAST[code] = ref
    if last is None or last() is fn or code in _WARNED:
        return
    _WARNED.add(code)
    warnings.warn(
        f"{caller}: {what} is a new function object with the same code as an "
        f"earlier call's ({code.co_name} at {code.co_filename}:"
        f"{code.co_firstlineno}), so its program is traced and compiled again. "
        "To reuse the compiled program, pass the same function object each time, "
        "or an equinox.Partial(f, *args) of a module-level f whose varying values "
        "are array arguments (warned once per function).",
        RecompilationWarning,
        stacklevel=3,
    )


def note_hooks(linkage, caller: str) -> None:
    """:func:`note_function` for a linkage's hooks (their static functions)."""
    for name in ("custom_wrench", "custom_actuation", "actuator_strength"):
        hook = getattr(linkage, name, None)
        fn = getattr(hook, "function", hook)  # a model.Hook: the user's function
        note_function(fn, f"Linkage.{name}", caller)
