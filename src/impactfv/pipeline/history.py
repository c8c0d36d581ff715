"""The history: one row per step, in preallocated columns that grow by doubling."""

from __future__ import annotations

import numpy as np


class History:
    def __init__(self, columns):
        self.columns = list(columns)
        self.data = {k: np.zeros(1024) for k in self.columns}
        self.n = 0

    def append(self, row):
        if self.n == len(self.data[self.columns[0]]):
            for k in self.columns:
                self.data[k] = np.concatenate([self.data[k], np.zeros(self.n)])
        for k, value in zip(self.columns, row):
            self.data[k][self.n] = value
        self.n += 1

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: self.data[k][:self.n].copy() for k in self.columns}

    def last(self) -> dict[str, float]:
        return {k: float(self.data[k][self.n - 1]) for k in self.columns}

    def load(self, columns: dict[str, np.ndarray]):
        """Replace the rows by ``columns`` (from a checkpoint)."""
        n = len(columns[self.columns[0]])
        for k in self.columns:
            self.data[k] = np.concatenate([columns[k], np.zeros(max(n, 1024))])
        self.n = n
