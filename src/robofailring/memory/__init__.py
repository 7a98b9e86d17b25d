"""The failure memory (paper Algorithm 1) and the success memory: their Faiss indexes, references, manifest and thinning."""
