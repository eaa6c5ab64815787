"""The command line: every argparse parser, and the printing of results, over the analogy API."""

from .commands import EXIT_ACCURACY, EXIT_FAILED, EXIT_OK, EXIT_USAGE, build_parser, main, scene_from_args

__all__ = ["EXIT_ACCURACY", "EXIT_FAILED", "EXIT_OK", "EXIT_USAGE", "build_parser", "main", "scene_from_args"]
