"""``recon skeleton``: the paper's 2D skeleton and decomposition of a shape (placeholder until wired)."""


def add_parser(sub):
    p = sub.add_parser("skeleton", help="2D skeleton and decomposition of a shape (§2–3)")
    p.set_defaults(func=lambda args: 0)
    return p
