"""Reading an HTTP Accept header."""

from __future__ import annotations


def accepted_media_types(accept: str) -> list[str]:
    """The media types of an Accept header, most wanted first (ties in header order; q=0 ones left out)."""
    offers = []
    for position, part in enumerate(accept.split(",")):
        media, *params = (piece.strip() for piece in part.split(";"))
        quality = 1.0
        for param in params:
            name, _, value = param.partition("=")
            if name.strip().lower() == "q":
                try:
                    quality = float(value)
                except ValueError:
                    quality = 0.0
        if quality > 0 and media:
            offers.append((-quality, position, media.lower()))
    return [media for _, _, media in sorted(offers)]
