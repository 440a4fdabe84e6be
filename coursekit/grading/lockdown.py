"""Keeping coursekit's own version of a graded function out of the student's answer, in the process that runs it.

Part of the summative grader (seed paper section 4, exercises graded; issue: the library's own
implementation is not the student's answer). Shipped with :mod:`coursekit.grading.values` and
:mod:`coursekit.grading.runner` as source text into the grading kernel, so standard library
only. :class:`Refusing` swaps the code of the library's versions for a stub that raises; in a
forked worker that only serves calls, :meth:`Refusing.forever` does so for good, copies made in
a cell included -- found by what they compute (:func:`_content`: the instructions, names and
loaded constants, whatever the name, file, docstring or local names) -- and :func:`lock_down`
adds an audit hook (PEP 578, never removable) that refuses what could fetch the library's code
around the stubs: compiling or loading it afresh, running code that defines a copy, compiling a
syntax tree, starting a fresh Python, C calls through ctypes (allowed where the sandbox withholds
the library, :data:`NATIVE`: numba compiles through them), rebuilding functions from code objects.

In sandboxed grading this is the second line: the functions it refuses are not in the sandbox
at all there (:mod:`.withheld`, in a run of their own where the library needs them elsewhere),
and what it stubs are their withheld stand-ins; it is the only line in ``--unsafe`` grading and
in the exercise's own ``check()``.

What it cannot see: the library's source pasted into a cell and edited, or any other copy with
instructions of its own (that is writing the function, as far as any grader can tell), or a
notebook that replaced the interpreter's own ``sys`` module before the worker started.
"""

from __future__ import annotations

import sys

if __name__ != "coursekit_harvest":  # imported; the harvest cell ships values.py's text into this namespace first
    from coursekit.grading.values import library_attr

#: The file name the stubs are compiled under.
STUB = "<coursekit-refused>"


class Refusing:
    """While active, coursekit's own versions of a graded function raise instead of running.

    Each ``"module:attr"`` of ``paths`` (a library function or method) gets the code of a stub
    that raises ``RuntimeError``, so every reference to it -- an import under another name, a
    wrapper that calls it, the library calling it internally -- refuses while the student's
    function runs; the code is put back on exit. Arguments are decoded and results converted
    outside, so the library itself stays usable there. :meth:`forever` (a forked worker that
    only serves calls) stubs them for good, copies included, and locks the process down.
    """

    def __init__(self, paths, function, native=False):
        self.native = native  # ctypes allowed after forever() (see lock_down)
        self.saved, self.copies = [], []  # (the library's function, its code, its stub); (code it is known by, its name)
        self.files, self.texts = set(), []
        for path in paths:
            try:
                obj = library_attr(path)
            except (ImportError, AttributeError, ValueError):
                continue
            obj = getattr(obj, "__func__", obj)
            if not hasattr(obj, "__code__") or obj.__code__.co_freevars:
                continue
            self._source(path)  # from the module's file: the function's code may be a stub already
            if obj.__code__.co_filename == STUB:  # refused already (a kernel locked down before this worker)
                continue
            name = path.partition(":")[2]
            self.saved.append((obj, obj.__code__, _stub(f"coursekit's own {name} is not available while your {function} "
                                                        f"is graded: {function} must do the work itself (the rest of "
                                                        "the library may be used)")))
            try:  # its definition compiled alone (as a cell would) gives other instructions than in its module
                fresh = compile(self.texts[-1], "<source>", "exec") if self.texts else None
            except SyntaxError:
                fresh = None
            self.copies.append((obj.__code__, name))
            self.copies += [(c, name) for c in (_nested(fresh) if fresh else ()) if c.co_name == obj.__name__]

    def _source(self, path):
        """Note the file of ``path``'s module and the source text of its definition (for
        :func:`lock_down`), read with ``tokenize`` (``inspect.getblock``): compiling it, even to
        an AST, is what a locked-down process refuses."""
        import inspect
        import re

        module, _, attr = path.partition(":")
        filename = getattr(sys.modules.get(module), "__file__", None)
        if not filename:
            return
        self.files.add(filename)
        try:
            with open(filename, encoding="utf-8") as f:
                lines = f.readlines()
        except OSError:
            return
        head = re.compile(rf"^\s*def {re.escape(attr.rpartition('.')[2])}\b")
        start = next((i for i, line in enumerate(lines) if head.match(line)), None)
        if start is not None:
            self.texts.append("".join(inspect.getblock(lines[start:])).strip())

    def __enter__(self):
        for obj, _, stub in self.saved:
            obj.__code__ = stub
        return self

    def __exit__(self, *exc):
        for obj, code, _ in self.saved:
            obj.__code__ = code
        return False

    def forever(self):
        """Stub the library's versions for the rest of this process, and every function or name that
        holds their code (a copy made in a cell); then :func:`lock_down` the process."""
        import gc

        # Objects moved to the permanent generation (gc.freeze: a gallery does it, and so can a
        # notebook) are invisible to get_referrers: bring them back first, or a copy made
        # before a freeze would keep the library's code.
        gc.unfreeze()
        # A copy rebuilt from the code in a cell before grading (code.replace with another name, file,
        # docstring or extra constants, or its source compiled again with such changes) is another code
        # object that computes the same: stubbed too. The cheap part of the key picks the candidates.
        same = {_content(code): name for code, name in self.copies}
        names, library = {key[1] for key in same}, {id(obj) for obj, _, _ in self.saved}
        for holder in gc.get_objects():
            code = getattr(holder, "__code__", None) if type(holder) is type(_content) else None
            if (code is not None and code.co_filename != STUB and id(holder) not in library and code.co_names in names
                    and _content(code) in same):
                holder.__code__ = _stub(f"{holder.__name__} has the instructions of coursekit's own {same[_content(code)]} "
                                        "(a copy made before grading, under another name): write your own")
        for obj, code, stub in self.saved:
            obj.__code__ = stub
            for holder in gc.get_referrers(code):
                if callable(holder) and getattr(holder, "__code__", None) is code:
                    holder.__code__ = stub
                elif type(holder) is dict:
                    for k in [k for k, v in holder.items() if v is code]:
                        holder[k] = stub
                elif type(holder) is list:
                    holder[:] = [stub if v is code else v for v in holder]
        files, texts, keys = frozenset(self.files), tuple(self.texts), frozenset(same)
        self.saved, self.copies = [], []  # the library's code is no longer held here, where a frame could reach it
        lock_down(files, texts, keys, native=self.native)


def _stub(message: str):
    """The code of a function that raises ``RuntimeError(message)``, compiled under :data:`STUB`."""
    ns = {}
    exec(compile(f"def stub(*args, **kwargs):\n    raise RuntimeError({message!r})", STUB, "exec"), ns)
    return ns["stub"].__code__


def _content(code):
    """What a code object computes, whatever its name, file, line numbers, docstring or unused
    constants: its instructions, the names they use and the constants they load (nested code by
    its content too). Any other change -- one more name, another constant, another operator --
    makes it other code, so code written for itself is not taken for the library's."""
    import dis

    loaded = tuple(_content(i.argval) if type(i.argval) is type(code) else (type(i.argval).__name__, repr(i.argval))
                   for i in dis.get_instructions(code) if i.opcode in dis.hasconst)
    return code.co_code, code.co_names, loaded


def _nested(code):
    """``code`` and every code object among its constants, all the way down."""
    yield code
    for c in code.co_consts:
        if type(c) is type(code):
            yield from _nested(c)


#: Audit events refused in a locked-down process: starting programs (a fresh Python would import
#: the library unrefused; a fork is allowed, it inherits the stubs and the hook), C calls through
#: ctypes (which could undo anything; :data:`NATIVE` where the sandbox withholds the library), and
#: rebuilding code (the library's own, restored into a function).
REFUSED_EVENTS = frozenset({
    "os.exec", "os.posix_spawn", "os.spawn", "os.system", "os.startfile", "subprocess.Popen",
    "pty.spawn", "ctypes.dlopen", "ctypes.dlsym", "ctypes.call_function", "ctypes.cdata", "ctypes.addressof",
    "code.__new__", "function.__new__"})
#: The events of :data:`REFUSED_EVENTS` that native code needs: numba and llvmlite compile a function
#: through ctypes when it is first called with new argument types. Allowed where the sandbox
#: withholds the library (there is nothing for C calls to reach); refused without a sandbox.
NATIVE = frozenset(e for e in REFUSED_EVENTS if e.startswith("ctypes."))


#: What a graded function hears when it tries to compile or load the library's code afresh.
RELOADED = ("coursekit's own code of the graded functions may not be compiled or loaded afresh while a function is "
            "graded: write the function yourself (the rest of the library may be used)")


def lock_down(files, texts, keys=frozenset(), native=False):
    """Make this process (a kernel or worker that only serves calls now) refuse, through an audit hook (PEP 578:
    it can never be removed), what could fetch the library's versions around the stubs: compiling
    or running code from their source files or with their source text (``inspect.getsource``,
    ``importlib``, a reload), running code that defines a copy of them (``keys``: their
    :func:`_content`), ``marshal``-loading it, setting a function's ``__code__``, and the
    events of :data:`REFUSED_EVENTS` (but those of :data:`NATIVE` with ``native``). Raises
    ``RuntimeError`` when the hook is not in place (a notebook that replaced
    ``sys.addaudithook``): the worker then refuses every call."""
    import dis  # noqa: F401  (for _content, loaded before the hook is in place)

    encoded = tuple(f.encode() for f in files)
    refused = REFUSED_EVENTS - NATIVE if native else REFUSED_EVENTS
    seen = []

    def hook(event, args):
        try:
            if event == "coursekit.lockdown":
                seen.append(args)
                return
            if event in refused:
                why = f"{event} is not available while a function is graded"
            elif event == "compile" and type(args[0]) not in (str, bytes):  # a syntax tree, built before grading
                why = "compiling a syntax tree is not available while a function is graded"
            elif event == "compile":
                source, filename = args[0], args[1]
                text = source.decode(errors="replace") if type(source) is bytes else source
                bad = filename in files or any(t in text for t in texts)
                why = RELOADED if bad else None
            elif event == "exec":  # the library's code, or code that defines a copy of it (compiled before grading)
                bad = getattr(args[0], "co_filename", None) in files or (
                    type(args[0]) is type(hook.__code__) and any(_content(c) in keys for c in _nested(args[0])))
                why = RELOADED if bad else None
            elif event == "marshal.loads":
                why = RELOADED if any(f in bytes(args[0]) for f in encoded) else None
            elif event == "object.__setattr__":  # a function's code: only ever to one of our stubs
                why = "changing a function's code is not available while a function is graded" \
                    if args[1] == "__code__" and getattr(args[2], "co_filename", None) != STUB else None
            else:
                why = None
        except Exception:  # something the hook could not read: refuse (fail closed)
            why = f"{event} could not be checked while a function is graded"
        if why:
            raise RuntimeError(why)

    if type(sys.addaudithook).__name__ != "builtin_function_or_method" or sys.addaudithook.__name__ != "addaudithook":
        raise RuntimeError("sys.addaudithook was replaced")
    sys.addaudithook(hook)
    token = object()
    sys.audit("coursekit.lockdown", token)
    if not seen or seen[0][0] is not token:
        raise RuntimeError("the audit hook did not take")
