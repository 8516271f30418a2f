"""The BERT sizes of a ``config.json`` and the names of its weights in a ``model.safetensors``
(Hugging Face's layout) for the Flax network of :mod:`jaxmotion.text.bert`: plain Python, so
that reading a configuration or a cached sentence never imports Flax."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

__all__ = ["BertConfig", "hf_parameter_names"]


@dataclasses.dataclass(frozen=True)
class BertConfig:
    """BERT sizes; the defaults are all-MiniLM-L6-v2's ``config.json``."""

    vocab_size: int = 30522
    hidden: int = 384
    layers: int = 6
    heads: int = 12
    intermediate: int = 1536
    max_positions: int = 512
    type_vocab: int = 2
    eps: float = 1e-12

    @classmethod
    def from_hf(cls, path) -> BertConfig:
        c = json.loads(Path(path).read_text())
        if (
            c.get("hidden_act", "gelu") != "gelu"
            or c.get("position_embedding_type", "absolute") != "absolute"
        ):
            raise ValueError(f"unsupported BERT variant in {path}")
        return cls(
            vocab_size=c["vocab_size"],
            hidden=c["hidden_size"],
            layers=c["num_hidden_layers"],
            heads=c["num_attention_heads"],
            intermediate=c["intermediate_size"],
            max_positions=c["max_position_embeddings"],
            type_vocab=c["type_vocab_size"],
            eps=c["layer_norm_eps"],
        )


def hf_parameter_names(cfg: BertConfig) -> dict[tuple, tuple[str, bool]]:
    """Map NNX parameter paths to (safetensors name, transpose?)."""
    names = {
        ("word", "embedding"): ("embeddings.word_embeddings.weight", False),
        ("position", "embedding"): ("embeddings.position_embeddings.weight", False),
        ("token_type", "embedding"): ("embeddings.token_type_embeddings.weight", False),
        ("embed_norm", "scale"): ("embeddings.LayerNorm.weight", False),
        ("embed_norm", "bias"): ("embeddings.LayerNorm.bias", False),
    }
    parts = {
        "query": "attention.self.query",
        "key": "attention.self.key",
        "value": "attention.self.value",
        "attn_out": "attention.output.dense",
        "ff_in": "intermediate.dense",
        "ff_out": "output.dense",
    }
    norms = {"attn_norm": "attention.output.LayerNorm", "ff_norm": "output.LayerNorm"}
    for i in range(cfg.layers):
        pre = f"encoder.layer.{i}."
        for ours, hf in parts.items():
            # torch Linear stores weight as [out, in]; NNX kernel is [in, out].
            names[("layers", i, ours, "kernel")] = (pre + hf + ".weight", True)
            names[("layers", i, ours, "bias")] = (pre + hf + ".bias", False)
        for ours, hf in norms.items():
            names[("layers", i, ours, "scale")] = (pre + hf + ".weight", False)
            names[("layers", i, ours, "bias")] = (pre + hf + ".bias", False)
    return names
