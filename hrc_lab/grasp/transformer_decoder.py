"""★ ``grasp.decoder=transformer``: a Transformer decoder for the grasp solutions, the thesis' future work (6.5:
"Transformer-based decoding models") in place of LSTM_Att (Eq. 6.4-6.6).

The decoder input f' = [Gamma_i, l_i, P_gra] (Eq. 6.7) is projected into ``segments`` memory tokens, as LSTM_Att
projects it into the segments it attends over (Eq. 6.4). ``transformer_layers`` decoder layers of width
``lstm_hidden`` with ``transformer_heads`` heads (masked self-attention over the words so far, cross-attention to the
memory) give each next word; the ground-truth words are the input in training (teacher forcing) and the greedy
choices at test, from <start>, as for LSTM_Att."""

from __future__ import annotations

import torch
from torch import nn

from hrc_lab.grasp.configs import GraspSolverConfig
from hrc_lab.vocabulary import START, TokenVocabulary


class TransformerSolutionDecoder(nn.Module):
    """Words of a grasp solution from f' (the interface of :class:`~hrc_lab.grasp.solver.AttentionLSTMDecoder`)."""

    def __init__(self, feature_dim: int, vocab: TokenVocabulary, cfg: GraspSolverConfig) -> None:
        super().__init__()
        self.vocab, self.segments, self.width = vocab, cfg.segments, cfg.lstm_hidden
        self.to_memory = nn.Linear(feature_dim, cfg.segments * self.width)
        self.word_embedding = nn.Embedding(len(vocab), self.width)
        self.position = nn.Embedding(vocab.max_len, self.width)
        layer = nn.TransformerDecoderLayer(self.width, cfg.transformer_heads, dim_feedforward=2 * self.width,
                                           dropout=0.0, batch_first=True)
        self.layers = nn.TransformerDecoder(layer, cfg.transformer_layers)
        self.word_head = nn.Linear(self.width, len(vocab))

    def _memory(self, features: torch.Tensor) -> torch.Tensor:
        return self.to_memory(features).view(len(features), self.segments, self.width)

    def _logits(self, memory: torch.Tensor, words: torch.Tensor) -> torch.Tensor:
        length = words.shape[1]
        inputs = self.word_embedding(words) + self.position.weight[:length]
        mask = nn.Transformer.generate_square_subsequent_mask(length, device=words.device)
        return self.word_head(self.layers(inputs, memory, tgt_mask=mask, tgt_is_causal=True))

    def forward(self, features: torch.Tensor, captions: torch.Tensor) -> torch.Tensor:
        """Teacher forcing: logits (B, L, vocab) of every word given the previous ground-truth words."""
        start = torch.full_like(captions[:, :1], self.vocab.index[START])
        return self._logits(self._memory(features), torch.cat([start, captions[:, :-1]], dim=1))

    @torch.no_grad()
    def greedy(self, features: torch.Tensor) -> torch.Tensor:
        """(B, max_len) word indices, each the most likely given the ones before."""
        memory = self._memory(features)
        words = torch.full((len(features), 1), self.vocab.index[START], dtype=torch.long, device=features.device)
        for _ in range(self.vocab.max_len):
            step = self._logits(memory, words)[:, -1]
            words = torch.cat([words, step.argmax(-1, keepdim=True)], dim=1)
        return words[:, 1:]
