"""Compose ``conf/`` into ``params.yaml``, exactly as ``dvc exp run -S`` does.

Usage: ``python -m locoman.config.compose [override ...] [--out FILE] [--check]``.
``--check`` compares instead of writing and exits 1 when the file is stale.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import yaml
from dvc.utils.hydra import compose_and_dump
from hydra.errors import HydraException
from omegaconf.errors import OmegaConfBaseException

from locoman.artifacts.io import write_text_atomic
from locoman.config.load import validate
from locoman.errors import ConfigError

CONF_DIR = Path("conf")


def compose_text(overrides: list[str], conf_dir: Path = CONF_DIR) -> str:
    """The composed ``params.yaml`` text, validated against the typed schema."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "params.yaml"
        try:
            compose_and_dump(str(out), str(conf_dir.resolve()), None, "config", "", overrides)
        except (HydraException, OmegaConfBaseException) as exc:
            # Hydra's own traceback runs to 30 frames; its first line names the key.
            cause = exc.__cause__ if isinstance(exc.__cause__, OmegaConfBaseException) else exc
            first = str(cause).strip().splitlines()[0] if str(cause).strip() else type(cause)
            raise ConfigError(
                f"cannot compose {conf_dir}/ with overrides {overrides}: {first}. A key that "
                "an interpolation ${...} or an override names must exist in conf/."
            ) from None
        text = out.read_text()
    validate(yaml.safe_load(text))
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("overrides", nargs="*", help="Hydra overrides, e.g. scenario.box_mass=2.5")
    parser.add_argument("--out", default="params.yaml")
    parser.add_argument("--check", action="store_true", help="fail if --out is stale")
    args = parser.parse_args(argv)
    try:
        text = compose_text(args.overrides)
    except ConfigError as exc:
        print(f"locoman: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    if args.check:
        if not out.is_file() or out.read_text() != text:
            print(f"{out} is stale against conf/; run `make params`", file=sys.stderr)
            return 1
        return 0
    write_text_atomic(out, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
