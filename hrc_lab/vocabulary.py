"""Word <-> id mapping of the text decoders (Ch.5 semantic plans, Ch.6 grasp solutions): padded to a fixed length,
ended by <end>."""

from __future__ import annotations

PAD, START, END = "<pad>", "<start>", "<end>"


class TokenVocabulary:
    """The control tokens (ids 0, 1, 2) then ``words``; ``max_len`` counts the closing <end>."""

    def __init__(self, words, max_len: int) -> None:
        self.words = [PAD, START, END, *(w for w in words if w not in (PAD, START, END))]
        self.index = {w: i for i, w in enumerate(self.words)}
        self.max_len = max_len

    def __len__(self) -> int:
        return len(self.words)

    def encode(self, tokens: list[str]) -> list[int]:
        ids = [self.index[t] for t in tokens] + [self.index[END]]
        return ids + [self.index[PAD]] * (self.max_len - len(ids))

    def decode(self, ids) -> list[str]:
        words = []
        for i in ids:
            word = self.words[int(i)]
            if word == END:
                break
            words.append(word)
        return words
