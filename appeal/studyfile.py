"""Study files: YAML in, validated pydantic models out, one-line errors per problem.

Every kind of study file (stimulus grid, runner protocol, rating analysis, ERP analysis) is
a :class:`StudyModel` subclass with a ``kind`` literal. :func:`load_study_file` reads the
YAML, resolves relative paths against the file's folder and turns every pydantic error
into a line ``FILE: dotted.path: message`` (unknown keys get a "did you mean").
"""

from __future__ import annotations

import difflib
import types
import typing
from pathlib import Path
from typing import Annotated, Any, TypeVar, Union

import yaml
from pydantic import AfterValidator, BaseModel, ConfigDict, ValidationError, ValidationInfo

from appeal.errors import AppealInputError, StudyFileError

__all__ = [
    "StudyModel",
    "InputFile",
    "InputDir",
    "InputPath",
    "OutputPath",
    "load_yaml",
    "load_study_file",
    "validate_data",
    "format_validation_error",
]

M = TypeVar("M", bound=BaseModel)


class StudyModel(BaseModel):
    """Base class for study-file models: unknown keys are errors, fields are typed."""

    model_config = ConfigDict(extra="forbid", validate_default=True)


# --------------------------------------------------------------------------- paths
def _base_dir(info: ValidationInfo) -> Path:
    ctx = info.context or {}
    return Path(ctx.get("base_dir", "."))


def _resolve(value: Path, info: ValidationInfo) -> Path:
    text = str(value)
    if text.startswith("data:"):  # a registered dataset (appeal data), not a path
        from appeal.datasets import resolve_reference

        try:
            return resolve_reference(text, missing_ok=not (info.context or {}).get("check_paths", True))
        except AppealInputError as exc:
            raise ValueError(str(exc)) from None
    value = Path(value).expanduser()
    if not value.is_absolute():
        value = _base_dir(info) / value
    return value.resolve()


def _existing_file(value: Path, info: ValidationInfo) -> Path:
    path = _resolve(value, info)
    if (info.context or {}).get("check_paths", True) and not path.is_file():
        raise ValueError(f"file not found: {path}")
    return path


def _existing_dir(value: Path, info: ValidationInfo) -> Path:
    path = _resolve(value, info)
    if (info.context or {}).get("check_paths", True) and not path.is_dir():
        raise ValueError(f"folder not found: {path}")
    return path


def _existing_path(value: Path, info: ValidationInfo) -> Path:
    path = _resolve(value, info)
    if (info.context or {}).get("check_paths", True) and not path.exists():
        raise ValueError(f"file or folder not found: {path}")
    return path


#: A file that must exist; relative paths resolve against the study file's folder.
InputFile = Annotated[Path, AfterValidator(_existing_file)]
#: A folder that must exist; relative paths resolve against the study file's folder.
InputDir = Annotated[Path, AfterValidator(_existing_dir)]
#: A file or folder that must exist.
InputPath = Annotated[Path, AfterValidator(_existing_path)]
#: A path that is resolved but need not exist (outputs, globs).
OutputPath = Annotated[Path, AfterValidator(_resolve)]


# --------------------------------------------------------------------------- YAML
def load_yaml(path: str | Path) -> Any:
    """Read a YAML file, turning I/O and syntax problems into one-line errors.

    Parameters
    ----------
    path : str | Path
        The file.

    Returns
    -------
    object
        The parsed document.

    Raises
    ------
    StudyFileError
        When the file is missing, unreadable or not valid YAML.
    """
    path = Path(path)
    if not path.exists():
        raise StudyFileError(f"{path}: file not found")
    if path.is_dir():
        raise StudyFileError(f"{path}: is a folder, expected a YAML file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise StudyFileError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise StudyFileError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark is not None else f"{path}"
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise StudyFileError(f"{where}: invalid YAML: {problem}") from None


# --------------------------------------------------------------------------- errors
def _loc_to_path(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def _short(value: Any, limit: int = 60) -> str:
    text = repr(value) if isinstance(value, str) else str(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _unwrap(annotation: Any) -> list[Any]:
    """The concrete types an annotation may hold (Optional/Union/Annotated unpacked)."""
    origin = typing.get_origin(annotation)
    if origin is Annotated:
        return _unwrap(typing.get_args(annotation)[0])
    if origin in (Union, types.UnionType):
        out: list[Any] = []
        for arg in typing.get_args(annotation):
            out.extend(_unwrap(arg))
        return out
    return [annotation]


def _models_at(model: type[BaseModel], loc: tuple[Any, ...]) -> list[type[BaseModel]]:
    """The model classes that may sit at ``loc`` below ``model`` (best effort)."""
    current: list[Any] = [model]
    for part in loc:
        nxt: list[Any] = []
        for ann in current:
            for typ in _unwrap(ann):
                origin = typing.get_origin(typ)
                if isinstance(typ, type) and issubclass(typ, BaseModel):
                    field = typ.model_fields.get(str(part))
                    if field is not None:
                        nxt.append(field.annotation)
                elif origin in (list, tuple, set, frozenset) and isinstance(part, int):
                    nxt.extend(a for a in typing.get_args(typ) if a is not Ellipsis)
                elif origin is dict:
                    args = typing.get_args(typ)
                    if len(args) == 2:
                        nxt.append(args[1])
        current = nxt
    return [t for ann in current for t in _unwrap(ann) if isinstance(t, type) and issubclass(t, BaseModel)]


def _did_you_mean(model: type[BaseModel], loc: tuple[Any, ...], key: str) -> str:
    names: list[str] = []
    for cls in _models_at(model, loc[:-1]):
        for name, field in cls.model_fields.items():
            names.append(field.alias or name)
    if not names:
        return ""
    close = difflib.get_close_matches(key, names, n=1, cutoff=0.6)
    if close:
        return f" (did you mean '{close[0]}'?)"
    return f" (expected one of: {', '.join(sorted(set(names)))})"


_COMPARISONS = {
    "greater_than": (">", "gt"),
    "greater_than_equal": (">=", "ge"),
    "less_than": ("<", "lt"),
    "less_than_equal": ("<=", "le"),
}


def _message(err: dict[str, Any], model: type[BaseModel]) -> str:
    kind = err["type"]
    ctx = err.get("ctx") or {}
    value = err.get("input")
    got = "" if isinstance(value, (dict, list)) else f" (got {_short(value)})"
    if kind == "missing":
        return "required field is missing"
    if kind == "extra_forbidden":
        key = str(err["loc"][-1])
        return f"unknown key '{key}'{_did_you_mean(model, tuple(err['loc']), key)}"
    if kind in _COMPARISONS:
        op, name = _COMPARISONS[kind]
        bound = ctx.get(name)
        if isinstance(bound, float) and bound.is_integer():
            bound = int(bound)
        return f"must be {op} {bound}{got}"
    if kind == "value_error":
        msg = str(ctx.get("error", err["msg"]))
        return msg + ("" if "(got" in msg or "not found" in msg else got)
    if kind == "assertion_error":
        return str(ctx.get("error", err["msg"])).removeprefix("Assertion failed, ")
    msg = err["msg"]
    msg = msg.replace("Input should be", "expected").replace("Value error, ", "")
    msg = msg.replace("a valid ", "").replace("Field required", "required field is missing")
    return f"{msg[0].lower()}{msg[1:]}{got}"


def format_validation_error(exc: ValidationError, source: str | Path, model: type[BaseModel]) -> list[str]:
    """Turn a pydantic :class:`~pydantic.ValidationError` into ``FILE: path: message`` lines.

    Parameters
    ----------
    exc : ValidationError
        The error pydantic raised.
    source : str | Path
        The file name to put at the start of each line.
    model : type of BaseModel
        The model that was validated (used for "did you mean" suggestions).

    Returns
    -------
    list of str
        One line per problem.
    """
    branches = _model_names(StudyModel)  # a union's model branch: 'shapes.ShapeContinuum.levels'
    errors = []
    for err in exc.errors(include_url=False):
        loc = tuple(p for p in err["loc"] if not (isinstance(p, str) and p.startswith("function-")))
        # drop union-branch tags pydantic inserts (e.g. 'list[float]', 'constrained-str')
        loc = tuple(p for p in loc if not (isinstance(p, str) and ("[" in p or p.endswith("-str") or p in branches)))
        errors.append(dict(err, loc=loc))
    # a union's branch of the wrong kind ("expected list" for a mapping) says nothing when the
    # branch of the right kind has its own complaint inside
    deeper = {e["loc"][:k] for e in errors for k in range(len(e["loc"]))}
    errors = [e for e in errors if not (e["type"].endswith("_type") and e["loc"] in deeper)]
    return list(dict.fromkeys(f"{source}: {_loc_to_path(e['loc'])}: {_message(e, model)}" for e in errors))


def _model_names(cls: type) -> set[str]:
    """The names of ``cls`` and every subclass of it."""
    return {cls.__name__}.union(*(_model_names(sub) for sub in cls.__subclasses__()))


# --------------------------------------------------------------------------- entry points
def validate_data(
    data: Any,
    model: type[M],
    *,
    source: str | Path = "<data>",
    base_dir: str | Path | None = None,
    check_paths: bool = True,
) -> M:
    """Validate an already-parsed study document.

    Parameters
    ----------
    data : object
        The parsed YAML document (normally a mapping).
    model : type of StudyModel
        The schema.
    source : str | Path
        Name used at the start of error lines.
    base_dir : str | Path | None
        Folder that relative paths resolve against (default: the current folder).
    check_paths : bool
        If False, input paths are resolved but not required to exist.

    Returns
    -------
    StudyModel
        The validated model.

    Raises
    ------
    StudyFileError
        One line per problem.
    """
    if not isinstance(data, dict):
        kind = "an empty file" if data is None else type(data).__name__
        raise StudyFileError(f"{source}: (top level): expected a mapping of keys to values, got {kind}")
    context = {"base_dir": Path(base_dir) if base_dir is not None else Path.cwd(), "check_paths": check_paths}
    try:
        return model.model_validate(data, context=context)
    except ValidationError as exc:
        raise StudyFileError(format_validation_error(exc, source, model)) from None


def load_study_file(path: str | Path, model: type[M], *, check_paths: bool = True) -> M:
    """Load and validate a YAML study file.

    Parameters
    ----------
    path : str | Path
        The YAML file. Relative paths inside it resolve against its folder.
    model : type of StudyModel
        The schema of this kind of study file.
    check_paths : bool
        If False, input files and folders named in the file need not exist.

    Returns
    -------
    StudyModel
        The validated model; a :class:`StudyFileError` with one
        ``FILE: dotted.path: message`` line per problem otherwise (as :func:`validate_data`).
    """
    path = Path(path)
    data = load_yaml(path)
    return validate_data(data, model, source=path, base_dir=path.resolve().parent, check_paths=check_paths)
