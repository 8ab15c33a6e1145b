"""Following a node tree's links the way Cycles' shader graph does: through reroutes, muted
nodes and node groups (which vanish), to the node that computes a socket's value
(``linked_source``), and which links count at all (``followed``)."""

from __future__ import annotations

from .errors import ShaderCompileError

#: Nodes whose value passes straight through (their first input of the socket's kind).
PASS_THROUGH = {"NodeReroute"}


def followed(socket) -> bool:
    """Whether a link into ``socket`` counts: Blender keeps links into sockets a node hides
    (a physical Sky Texture's Vector) or that are muted, and Cycles drops them, so that the
    socket reads its coordinate as if unlinked."""
    return socket.is_linked and socket.links[0].is_valid and not socket.links[0].is_muted


def linked_source(socket, groups, owner: str):
    """What feeds an input socket, through reroutes, muted nodes and node groups:
    (output socket, group stack) of the node that computes it, or (None, the unlinked
    input socket whose own value it takes; inside a group that is the group node's).
    owner: the tree's user, named when its groups nest past any sensible depth."""
    for _ in range(256):
        if not followed(socket):
            return None, socket
        link = socket.links[0]
        node, output = link.from_node, link.from_socket
        if node.bl_idname in PASS_THROUGH or (node.mute and node.inputs):
            inputs = [i for i in node.inputs if i.type == output.type] or list(node.inputs)
            socket = inputs[0]
            continue
        if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None:
            outputs = [n for n in node.node_tree.nodes if n.bl_idname == "NodeGroupOutput"]
            active = [n for n in outputs if n.is_active_output] or outputs
            inner = active[0].inputs.get(output.name) if active else None
            if inner is None:
                return None, socket
            groups = groups + (node,)
            socket = inner
            continue
        if node.bl_idname == "NodeGroupInput" and groups:
            outer = groups[-1].inputs.get(output.name)
            if outer is None:
                return None, socket
            groups = groups[:-1]
            socket = outer
            continue
        return output, groups
    raise ShaderCompileError(f"{owner}: its node groups nest too deep")
