"""Loading and validating the composed configuration (``params.yaml``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from locoman.config.schema import RootCfg, walk_checks
from locoman.errors import ConfigError

PARAMS_FILE = Path("params.yaml")


def validate(raw: dict[str, Any]) -> RootCfg:
    """Typed configuration from a plain mapping.

    Raises:
        ConfigError: For an unknown key, a missing value, a wrong type or a value out of range;
            the message names the key's full path.
    """
    try:
        merged = OmegaConf.merge(OmegaConf.structured(RootCfg), OmegaConf.create(raw))
        cfg = OmegaConf.to_object(merged)
    except OmegaConfBaseException as exc:
        key = getattr(exc, "full_key", None) or "?"
        msg = str(exc).splitlines()[0]
        raise ConfigError(
            f"bad configuration key {key!r}: {msg}. Fix conf/ and run `make params`."
        ) from None
    assert isinstance(cfg, RootCfg)
    errors = walk_checks(cfg)
    if errors:
        lines = "\n".join(f"  {key}: {msg}" for key, msg in errors)
        raise ConfigError(f"invalid configuration values:\n{lines}")
    return cfg


def load_params(path: str | Path = PARAMS_FILE) -> RootCfg:
    """Read and validate the composed parameters file that DVC tracks."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path} is missing; compose it from conf/ with `make params`")
    return validate(read_mapping(path, "a mapping at the top level"))


def read_mapping(path: Path, what: str) -> dict:
    """The YAML mapping in ``path``.

    Raises:
        ConfigError: YAML cannot read it (its line and column named), or it holds no
            mapping (``what`` says what it should hold).
    """
    try:
        raw = yaml.safe_load(Path(path).read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path} is not valid YAML: {' '.join(str(exc).split())}") from None
    if not isinstance(raw, dict):
        raise ConfigError(f"{path} must hold {what}")
    return raw
