"""Request bodies whose text is real Unicode.

JSON may escape a lone surrogate (`"\\ud800"`); Python decodes it into a string no encoder accepts, so it
would fail later, while being hashed into a receipt or stored in SQLite, as a 500. Every request model
derives from UnicodeModel, which refuses such text with a 422 naming the field."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, model_validator


def surrogate_at(value: str) -> int | None:
    """Where an unpaired surrogate stands in `value`, or None when it is valid Unicode text."""
    if value.isascii():  # known without reading it: a whole re-published graph is checked in no time
        return None
    try:
        value.encode("utf-8")
    except UnicodeEncodeError as error:
        return error.start
    return None


class UnicodeModel(BaseModel):
    @model_validator(mode="after")
    def _unicode_text(self) -> Any:
        for name in type(self).model_fields:
            value = getattr(self, name)
            if isinstance(value, str) and (position := surrogate_at(value)) is not None:
                raise ValueError(
                    f"'{name}' holds an unpaired surrogate ({value[position]!a}) at character {position}: "
                    "not valid Unicode text"
                )
        return self
