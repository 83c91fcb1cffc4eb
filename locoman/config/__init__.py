"""Typed configuration: schema (dataclasses), loading/validation, composition from conf/."""

from locoman.config.load import load_params, validate
from locoman.config.schema import RootCfg, ScenarioCfg

__all__ = ["RootCfg", "ScenarioCfg", "load_params", "validate"]
