"""Evaluation: score a run's model or the geometric baseline on a split with the cone metrics
(`run`), the figures (`plots`), the non-learned geometric baseline (`geometric`), and the CLI
(`command`)."""
