"""The labelling page: people answer the schemes' questions (online, offline, study)."""

# Clip width and height in pixels: about the size a clip takes on a laptop screen (two side
# by side in the page's 980-pixel column), so it is not scaled up into a blur; rendering
# and encoding one 50-frame clip takes about a second on a CPU, ahead of time.
CLIP_SIZE = 384
