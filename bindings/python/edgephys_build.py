"""PEP 517 build backend for the edgephys package, standard library only.

The package is pure Python (ctypes over libedgephys), so a wheel is a zip of edgephys/*.py with
its metadata. No setuptools or wheel package is needed: `pip install` works offline, with or
without build isolation, on any interpreter with pip.
"""
import base64
import hashlib
import os
import zipfile

NAME = "edgephys"
VERSION = "0.1.0"
SUMMARY = "edgephys client SDK for Python (ctypes over the C API of libedgephys)"
_HERE = os.path.dirname(os.path.abspath(__file__))
_TAG = "py3-none-any"


def _dist_info():
    return f"{NAME}-{VERSION}.dist-info"


def _metadata():
    return (f"Metadata-Version: 2.1\nName: {NAME}\nVersion: {VERSION}\nSummary: {SUMMARY}\n"
            "Requires-Python: >=3.8\n")


def _wheel_file():
    return f"Wheel-Version: 1.0\nGenerator: edgephys_build\nRoot-Is-Purelib: true\nTag: {_TAG}\n"


def _package_files():
    package = os.path.join(_HERE, NAME)
    for name in sorted(os.listdir(package)):
        if name.endswith(".py"):
            with open(os.path.join(package, name), "rb") as f:
                yield f"{NAME}/{name}", f.read()


def _record_line(path, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{path},sha256={digest},{len(data)}\n"


def get_requires_for_build_wheel(config_settings=None):
    return []


def prepare_metadata_for_build_wheel(metadata_directory, config_settings=None):
    target = os.path.join(metadata_directory, _dist_info())
    os.makedirs(target, exist_ok=True)
    with open(os.path.join(target, "METADATA"), "w") as f:
        f.write(_metadata())
    with open(os.path.join(target, "WHEEL"), "w") as f:
        f.write(_wheel_file())
    return _dist_info()


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    filename = f"{NAME}-{VERSION}-{_TAG}.whl"
    files = list(_package_files())
    files.append((f"{_dist_info()}/METADATA", _metadata().encode()))
    files.append((f"{_dist_info()}/WHEEL", _wheel_file().encode()))
    record = "".join(_record_line(path, data) for path, data in files) + f"{_dist_info()}/RECORD,,\n"
    with zipfile.ZipFile(os.path.join(wheel_directory, filename), "w", zipfile.ZIP_DEFLATED) as whl:
        for path, data in files:
            whl.writestr(path, data)
        whl.writestr(f"{_dist_info()}/RECORD", record)
    return filename
