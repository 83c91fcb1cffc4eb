"""Compose ``conf/`` into ``params.yaml``, exactly as ``dvc exp run -S`` does.

Usage: ``python -m locoman.config.compose [override ...] [--out FILE] [--check]``.
``--check`` compares instead of writing and exits 1 when the file is stale.

A scenario is one file of ``conf/scenario/``. Hydra's defaults list names each config it
composes, so before composing, this brings the list in ``conf/config.yaml`` in step with the
files (the lines between ``# scenarios: begin`` and ``# scenarios: end``) and with them the
G1 scenarios (``humanoid_scenarios``, which the stages' scenario lists default to): adding a
scenario is adding its file and running ``make params``. ``dvc exp run`` composes the same
``conf/config.yaml``, so it sees the scenarios that ``make params`` last listed.
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
from pathlib import Path

import yaml
from dvc.utils.hydra import compose_and_dump
from hydra.errors import HydraException
from omegaconf.errors import OmegaConfBaseException

from locoman.artifacts.io import write_text_atomic
from locoman.config.load import read_mapping, validate
from locoman.config.schema import RootCfg
from locoman.errors import ConfigError

CONF_DIR = Path("conf")
BEGIN, END, HUMANOID = "# scenarios: begin", "# scenarios: end", "# scenarios: humanoid"


def scenario_files(conf_dir: Path = CONF_DIR) -> dict[str, dict]:
    """Each scenario file's name and content, in the defaults list's order (those it
    already names first, new ones after, by name).

    Raises:
        ConfigError: A file YAML cannot read, or one that is not a mapping.
    """
    found = {
        path.stem: read_mapping(path, "a mapping (robot, objects, plan, ...)")
        for path in sorted((conf_dir / "scenario").glob("*.yaml"))
    }
    listed = _listed(conf_dir)
    order = [n for n in listed if n in found] + [n for n in found if n not in listed]
    return {n: found[n] for n in order}


def _listed(conf_dir: Path) -> list[str]:
    text = (conf_dir / "config.yaml").read_text()
    return re.findall(r"- scenario@scenarios\.(\w+):", text)


def _first_line(exc: Exception) -> str:
    return " ".join(str(exc).split())


def check_scenario_files(cfg: RootCfg, conf_dir: Path = CONF_DIR) -> None:
    """Every scenario file of ``conf_dir`` is one of the composed ``cfg``'s scenarios.

    Raises:
        ConfigError: A file that ``params.yaml`` lacks (a scenario added without
            ``make params``), naming it.
    """
    if not (conf_dir / "scenario").is_dir():
        return  # a copy of the parameters without conf/: nothing to compare
    missing = sorted(set(scenario_files(conf_dir)) - set(cfg.scenarios))
    if missing:
        raise ConfigError(
            f"conf/scenario/ has {missing}, which params.yaml lacks: run `make params`"
        )


def sync_scenarios(conf_dir: Path = CONF_DIR) -> bool:
    """Bring ``conf/config.yaml``'s scenario lines and ``humanoid_scenarios`` in step with
    the files of ``conf/scenario/``; return whether the file changed.

    Raises:
        ConfigError: ``conf/config.yaml`` lacks the marked lines, or a scenario file is not
            YAML.
    """
    path = conf_dir / "config.yaml"
    text = path.read_text()
    files = scenario_files(conf_dir)
    lines = text.split("\n")
    try:
        start = next(i for i, ln in enumerate(lines) if ln.strip() == BEGIN)
        end = next(i for i, ln in enumerate(lines) if ln.strip() == END)
        humanoid = next(i for i, ln in enumerate(lines) if ln.rstrip().endswith(HUMANOID))
    except StopIteration:
        raise ConfigError(
            f"{path} lacks its marked scenario lines ({BEGIN!r} ... {END!r}, and "
            f"'humanoid_scenarios: [...]  {HUMANOID}'): restore them from git"
        ) from None
    indent = lines[start][: len(lines[start]) - len(lines[start].lstrip())]
    entries = [f"{indent}- scenario@scenarios.{n}: {n}" for n in files]
    g1 = [n for n, content in files.items() if content.get("robot") == "g1"]
    lines[humanoid] = f"humanoid_scenarios: [{', '.join(g1)}]  {HUMANOID}"
    lines[start + 1 : end] = entries
    new = "\n".join(lines)
    if new == text:
        return False
    write_text_atomic(path, new)
    return True


def compose_text(overrides: list[str], conf_dir: Path = CONF_DIR) -> str:
    """The composed ``params.yaml`` text, validated against the typed schema."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "params.yaml"
        try:
            compose_and_dump(str(out), str(conf_dir.resolve()), None, "config", "", overrides)
        except yaml.YAMLError as exc:
            # A file of conf/ that YAML cannot read: its name, line and column say where.
            raise ConfigError(
                f"a file of {conf_dir}/ is not valid YAML: {_first_line(exc)}. Fix it there "
                "(params.yaml is left as it was)"
            ) from None
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
        if not args.check and sync_scenarios():
            print("locoman: conf/config.yaml lists conf/scenario/'s files anew", file=sys.stderr)
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
