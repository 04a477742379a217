"""ISM+DO companion controller.

Importing :mod:`companion` or :mod:`companion.control` pulls in only NumPy: the asyncio
process, MAVLink and plotting live in submodules that are imported when used.
"""

__version__ = "0.1.0"
