"""Open Image Denoise, the library Blender ships (and its compositor's Denoise node runs),
called through ctypes: the final image denoised with its albedo and normal as guides.

The library is found beside Blender's own binaries: the ``lib`` folder of the ``bpy``
module (pip's bpy) or of Blender's installation.  Where it is missing, ``available``
says so and the render is kept as it is.
"""

from __future__ import annotations

import ctypes
import glob
import os
import threading

import numpy as np

#: OIDN's C API constants (oidn.h): the CPU device, three-float pixels.
_DEVICE_CPU = 1
_FORMAT_FLOAT3 = 3

_library = None
_lock = threading.Lock()


def _candidates() -> list[str]:
    """Library files in a ``lib`` folder of the folders holding Blender's Python modules or
    its binary, or of their parents (pip's bpy keeps it in site-packages/bpy/lib, Blender's
    installations beside the binary)."""
    starts = []
    try:
        import bpy
        starts += [os.path.dirname(bpy.__file__), bpy.app.binary_path or ""]
    except ImportError:
        pass
    folders = []
    for start in filter(None, starts):
        folder = os.path.abspath(start)
        for _ in range(6):
            folders.append(os.path.join(folder, "lib"))
            folder = os.path.dirname(folder)
    found = []
    for folder in folders:
        for pattern in ("libOpenImageDenoise.so*", "libOpenImageDenoise*.dylib",
                        "OpenImageDenoise.dll"):
            found += sorted(glob.glob(os.path.join(folder, pattern)))
    return found


def _load():
    """The library, loaded once (None where it cannot be)."""
    global _library
    with _lock:
        if _library is None:
            _library = False
            for path in _candidates():
                try:
                    library = ctypes.CDLL(path)
                except OSError:
                    continue
                _declare(library)
                _library = library
                break
        return _library or None


def _declare(lib) -> None:
    pointer, text, size = ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t
    lib.oidnNewDevice.restype = pointer
    lib.oidnNewDevice.argtypes = [ctypes.c_int]
    lib.oidnCommitDevice.argtypes = [pointer]
    lib.oidnNewFilter.restype = pointer
    lib.oidnNewFilter.argtypes = [pointer, text]
    lib.oidnSetSharedFilterImage.argtypes = [pointer, text, pointer, ctypes.c_int, size, size,
                                             size, size, size]
    lib.oidnSetFilterBool.argtypes = [pointer, text, ctypes.c_bool]
    lib.oidnSetFilterInt.argtypes = [pointer, text, ctypes.c_int]
    lib.oidnCommitFilter.argtypes = [pointer]
    lib.oidnExecuteFilter.argtypes = [pointer]
    lib.oidnGetDeviceError.restype = ctypes.c_int
    lib.oidnGetDeviceError.argtypes = [pointer, ctypes.POINTER(ctypes.c_char_p)]
    lib.oidnReleaseFilter.argtypes = [pointer]
    lib.oidnReleaseDevice.argtypes = [pointer]


def available() -> bool:
    """Whether Open Image Denoise can run here."""
    return _load() is not None


class DenoiseError(RuntimeError):
    """The library reported an error; the message is its own."""


def denoise(colour: np.ndarray, albedo: np.ndarray | None = None,
            normal: np.ndarray | None = None, threads: int = 0) -> np.ndarray:
    """(H, W, 3) float32 the denoised scene-linear ``colour`` (H, W, 3), guided by the
    first hits' ``albedo`` and ``normal`` (H, W, 3) when given (OIDN's "RT" filter, HDR).
    threads: 0 lets the library choose."""
    lib = _load()
    if lib is None:
        raise DenoiseError("Open Image Denoise was not found beside Blender's libraries")
    height, width = colour.shape[:2]
    images = {"color": colour}
    if albedo is not None:
        images["albedo"] = albedo
        if normal is not None:
            images["normal"] = normal
    arrays = {name: np.ascontiguousarray(np.nan_to_num(image[..., :3]), np.float32)
              for name, image in images.items()}
    output = np.empty((height, width, 3), np.float32)
    device = lib.oidnNewDevice(_DEVICE_CPU)
    if not device:
        raise DenoiseError("Open Image Denoise could not create its CPU device")
    try:
        if threads:
            lib.oidnSetDeviceInt = getattr(lib, "oidnSetDeviceInt")
            lib.oidnSetDeviceInt.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]
            lib.oidnSetDeviceInt(device, b"numThreads", int(threads))
        lib.oidnCommitDevice(device)
        flt = lib.oidnNewFilter(device, b"RT")
        try:
            for name, array in list(arrays.items()) + [("output", output)]:
                lib.oidnSetSharedFilterImage(flt, name.encode(), array.ctypes.data,
                                             _FORMAT_FLOAT3, width, height, 0, 0, 0)
            lib.oidnSetFilterBool(flt, b"hdr", True)
            if "albedo" in arrays:
                # The guides come from the same noisy samples as the colour: let the
                # filter clean them too.
                lib.oidnSetFilterBool(flt, b"cleanAux", False)
            lib.oidnCommitFilter(flt)
            lib.oidnExecuteFilter(flt)
            message = ctypes.c_char_p()
            if lib.oidnGetDeviceError(device, ctypes.byref(message)):
                raise DenoiseError(f"Open Image Denoise: "
                                   f"{(message.value or b'unknown error').decode()}")
        finally:
            lib.oidnReleaseFilter(flt)
    finally:
        lib.oidnReleaseDevice(device)
    return output
