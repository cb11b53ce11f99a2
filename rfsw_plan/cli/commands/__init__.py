"""One module per ``rfsw-plan`` subcommand.

Each module defines ``NAME`` (the subcommand), ``HELP`` (one line) and
``register(parser: argparse.ArgumentParser) -> None`` plus ``run(args) -> int``. The CLI
discovers the modules in this package, so adding a subcommand touches no shared file.
"""
