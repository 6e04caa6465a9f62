"""The paper's published numbers (Wang et al. 2024, section 4.2), for the report to set beside ours.

Figures 7-10 are published as images only; their captions and text give no numbers, so for them we
quote the qualitative claim the text makes.
"""
from __future__ import annotations

# Tables 1 and 2 of the paper travel with the accuracy study's data files (paper_* columns).
#: Table 3: mean collisions within 500 episodes (None = not converged).
TABLE3 = {
    "sarsa": {"5x5": 192.3, "7x7": None, "11x11": None},
    "constrained": {"5x5": 29.51, "7x7": 55.74, "11x11": 144.62},
    "fewshot": {"5x5": 8.77, "7x7": 18.39, "11x11": 48.44},
    "fewshot_dss": {"5x5": 7.145, "7x7": 9.75, "11x11": 15.9},
}
CLAIMS = {
    "fig7": "All compared methods find the optimal path within 500 episodes (5x5).",
    "fig8": "Methods with a safety guarantee collide far less than Q-learning; SSRL and few-shot "
            "reasoning without the dynamic support set are comparable and both beat the shield; SSRL "
            "is slightly better than few-shot without the dynamic support set.",
    "fig9": "The four substitution ways are comparable and all collide less than few-shot reasoning "
            "without substitution.",
    "fig10": "Carrying the support set over to the following experiments (long-term autonomy) reduces "
             "collisions to a very low level compared with restoring it.",
    "table3": "Sarsa > constrained RL > few-shot without DSS > few-shot with DSS on every maze; the DSS "
              "gain grows with maze size.",
}
