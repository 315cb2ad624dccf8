"""``python -m pfslam.cli``: the ``pfslam`` program."""

from pfslam.cli import main

main()
