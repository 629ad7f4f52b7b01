"""Downloads the SAIL paper's teacher files: ``python -m torchrl_sail.data.download [names] [--dest DIR]``.

The same command is installed as the console script ``torchrl-sail-teachers``. The code, and the
Python API (:func:`~torchrl_sail.data.download_paper_teachers`,
:func:`~torchrl_sail.data.paper_teachers_dir`), is in :mod:`torchrl_sail.data.paper_teachers`.
"""

import sys

from torchrl_sail.data.paper_teachers import main

if __name__ == "__main__":
    sys.exit(main())
