"""First code a Glint render worker process runs: ``python _worker_boot.py FD`` (``core.workers``
starts it).

The worker must import ``core`` under the very name the parent imported it as, so that the
pickled context's classes resolve to the same modules: ``core`` from a checkout,
``glint.core`` for ``render.py``, ``bl_ext.user_default.glint.core`` inside Blender.  Those
parents are add-on packages whose ``__init__`` imports ``bpy``, which a plain Python worker
must not (and inside Blender cannot) run, so they are stood in for by empty package modules
and ``core`` alone is loaded from its folder, as ``render.py``'s ``import_glint`` loads the
checkout.  This file uses no relative import: it runs before its package exists.
"""

import importlib
import importlib.util
import os
import sys
import types


def load_core(name: str, folder: str):
    """The core package as ``name`` (e.g. 'glint.core'), loaded from ``folder``."""
    if name in sys.modules:
        return sys.modules[name]
    parts = name.split(".")
    for i in range(1, len(parts)):
        parent = ".".join(parts[:i])
        if parent not in sys.modules:
            stand_in = types.ModuleType(parent)
            stand_in.__path__ = []   # a package, with nothing importable but what we add
            sys.modules[parent] = stand_in
    spec = importlib.util.spec_from_file_location(
        name, os.path.join(folder, "__init__.py"), submodule_search_locations=[folder])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def main(descriptor: int) -> None:
    """Connect to the parent over the socket ``descriptor``, take its settings (sys.path and
    where core is), import core and serve tiles (``core.worker_process.worker_loop``)."""
    import signal
    from multiprocessing.connection import Connection

    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C reaches the whole group: the
    connection = Connection(descriptor)             # parent decides and stops us
    try:
        setup = connection.recv()                   # builtins only: nothing imported yet
    except EOFError:
        return
    # The parent's path entries go after this interpreter's own (its standard library and
    # site-packages): a parent may have a folder at the front of its path (pytest puts the
    # checkout's parent there) in which a stray inspect.py or dataclasses.py would shadow the
    # standard library for a process that imports everything afresh.
    own = list(sys.path)
    sys.path[:] = own + [entry for entry in setup["sys_path"] if entry not in own]
    load_core(setup["core_name"], setup["core_folder"])
    worker = importlib.import_module(setup["core_name"] + ".worker_process")
    worker.worker_loop(connection, setup)


if __name__ == "__main__":
    main(int(sys.argv[1]))
