"""Entry point of the child process that reads an ANSYS result file (:func:`fem_import.ansys_rst.read_ansys_rst`).

``python -m fem_import._rst_child RST OUT.npz SUBCASE_JSON``: the library's C reader may abort the process on a
damaged file, so the toolkit reads ``.rst`` files here and not in the user's process.
"""

import json
import sys

from fem_import.ansys_rst import _child

if __name__ == "__main__":
    _child(sys.argv[1], sys.argv[2], json.loads(sys.argv[3]))
