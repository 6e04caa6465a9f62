"""Safe reinforcement learning: the methods, their rules, the kernel and the runner."""
