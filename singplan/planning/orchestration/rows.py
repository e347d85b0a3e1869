"""Rows of a long program kept in blocks while its moves are planned, stitched into one array once."""

from __future__ import annotations

import math
import mmap

import numpy as np

BLOCK_ROWS = 65_536  # rows a block holds (3 MB of six joints' samples): given back whole once stitched


class RowStore:
    """Rows of one shape appended a move at a time, each copied into a block: a long program then
    keeps no array of its own per move, whose room the heap would keep after they are stitched and
    the record's arrays come on top of it.

    A block is an anonymous memory map of its own (:func:`_block`), not the allocator's: whatever
    the allocator's threshold for mapping large requests apart (glibc raises it as the process
    frees large arrays), a block freed is given back to the system whole, and its rows not yet
    written take no memory.

    ``tail``: the shape of one row, () for scalars (each block is (rows, *tail)).
    """

    def __init__(self, tail: tuple[int, ...] = ()) -> None:
        self.tail = tail
        self.blocks: list[np.ndarray] = []  # each (rows, *tail)
        self.filled: list[int] = []  # rows taken in each block

    def kept(self, rows: np.ndarray) -> np.ndarray:
        """``rows`` copied into a block: a view of the copy (the same values, bit for bit)."""
        if not self.blocks or self.filled[-1] + len(rows) > len(self.blocks[-1]):
            self.blocks.append(_block((max(BLOCK_ROWS, len(rows)), *self.tail)))
            self.filled.append(0)
        a = self.filled[-1]
        view = self.blocks[-1][a:a + len(rows)]
        view[...] = rows
        self.filled[-1] = a + len(rows)
        return view

    def stitched(self) -> np.ndarray:
        """Every row kept, in order, in one array (rows, *tail); the store is emptied (its blocks given back
        where no view of them is held)."""
        out = np.concatenate([b[:n] for b, n in zip(self.blocks, self.filled, strict=True)]) if self.blocks \
            else np.empty((0, *self.tail))
        self.blocks, self.filled = [], []
        return out


def _block(shape: tuple[int, ...]) -> np.ndarray:
    """A float array of ``shape`` in an anonymous memory map of its own (zero-filled by the system, its pages
    taken only when written; unmapped when the array and every view of it are freed)."""
    return np.frombuffer(mmap.mmap(-1, max(math.prod(shape), 1) * 8), dtype=float)[:math.prod(shape)].reshape(shape)
