"""Counter-based uniform draws keyed by (seed, link, seq): BLAKE2b, no generator state.

Each message gets one BLAKE2b-512 digest of
``b"tidelink/netmodel/v1\\0" || seed (8 bytes LE) || len(link) (4 bytes LE) || link (UTF-8)
|| seq (8 bytes LE)``; its 64 bytes are read as eight little-endian uint64 words and the top 53
bits of word j give the uniform ``(w >> 11) * 2**-53`` in [0, 1), exactly representable, so the
draws are bit-identical on every machine and do not depend on the order in which sequence
numbers are decided. Each purpose owns a fixed word (the ``U_*`` slots below), so adding a
feature never shifts another feature's draws.

This is deliberately not an ``np.random.Generator``: a generator's output depends on how many
draws came before, which would tie a link's decisions to arrival order across runtimes.
"""

from __future__ import annotations

import hashlib
import struct

DOMAIN = b"tidelink/netmodel/v1\0"
N_DRAWS = 8

# Fixed slots (word index) of the uniform draws for one message.
U_LOSS = 0  # Bernoulli loss, or the Gilbert-Elliott per-state loss
U_GE_STATE = 1  # Gilbert-Elliott state transition (or the stationary initial state)
U_DUPLICATE = 2  # whether the message is duplicated
U_DELAY = 3  # jitter of the original copy
U_DELAY_DUP = 4  # jitter of the duplicate copy (independent of the original)
U_FRAME_ERROR = 5  # an acoustic frame's bit errors (common/netmodel/acoustic_link.py)
# words 5..7 are reserved

_WORDS = struct.Struct("<8Q")
_SCALE = 2.0**-53


class CounterRng:
    """Eight independent uniforms in [0, 1) per (seed, link, seq), from a keyed hash."""

    def __init__(self, *, seed: int, link: str) -> None:
        if not (0 <= seed < 2**64):
            raise ValueError(f"seed: {seed!r} is invalid, expected an integer in [0, 2**64)")
        raw = link.encode("utf-8")
        prefix = DOMAIN + seed.to_bytes(8, "little") + len(raw).to_bytes(4, "little") + raw
        # the prefix is hashed once; each draw copies the hash state and appends the counter
        self._base = hashlib.blake2b(prefix, digest_size=64)

    def words(self, seq: int) -> tuple[int, ...]:
        """The eight raw 64-bit words for ``seq`` (0 <= seq < 2**64)."""
        h = self._base.copy()
        h.update(seq.to_bytes(8, "little"))
        return _WORDS.unpack(h.digest())

    def uniforms(self, seq: int) -> tuple[float, ...]:
        """The eight uniforms in [0, 1) for ``seq``; index them with the ``U_*`` slots."""
        return tuple([(w >> 11) * _SCALE for w in self.words(seq)])


def unit(word: int) -> float:
    """The uniform in [0, 1) that a 64-bit word stands for: its top 53 bits times 2**-53."""
    return (word >> 11) * _SCALE
