"""python -m ipsph.scene > docs/scene-reference.md"""

from . import reference_markdown

print(reference_markdown(), end="")
