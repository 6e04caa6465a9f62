"""Few-shot recognition: the Relation Network, the Prototypical Network, the dynamic support set."""
