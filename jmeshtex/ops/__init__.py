"""Pure, jit/vmap/grad-safe operators over padded neighbourhood arrays (parameters passed explicitly)."""

# -- public names added by each module below this line (one `from ._x import y as y` per name) --
from ._face_conv import EdgeFrames as EdgeFrames
from ._face_conv import FaceConvParams as FaceConvParams
from ._face_conv import FaceConvStackParams as FaceConvStackParams
from ._face_conv import FaceEmbedParams as FaceEmbedParams
from ._face_conv import edge_frames as edge_frames
from ._face_conv import face_conv as face_conv
from ._face_conv import face_conv_stack as face_conv_stack
from ._face_conv import face_edge_embed as face_edge_embed
from ._face_conv import face_features as face_features
from ._face_conv import face_to_vertex_displacement as face_to_vertex_displacement
from ._face_conv import init_face_conv_stack as init_face_conv_stack
from ._face_conv import instance_norm as instance_norm
from ._chamfer import ChamferDistance as ChamferDistance
from ._chamfer import NearestNeighbors as NearestNeighbors
from ._chamfer import chamfer_distance as chamfer_distance
from ._chamfer import nearest_neighbor as nearest_neighbor
from ._texel import PoolGroups as PoolGroups
from ._texel import TexelNeighborhood as TexelNeighborhood
from ._texel import grouped_pool as grouped_pool
from ._texel import image_pool_groups as image_pool_groups
from ._texel import image_texel_neighborhood as image_texel_neighborhood
from ._texel import texel_conv as texel_conv
from ._gram import gram_matrix as gram_matrix
