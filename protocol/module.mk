# protocol/module.mk - the wire protocol library libseamtex_proto.a (objects listed by the top
# Makefile as PROTO_OBJ). Included by the top Makefile.
#
# protocol/ depends on nothing but libc: its objects are compiled with protocol/ as the only
# include directory (INC_protocol in the top Makefile), so an #include of a store/, server/ or
# client/ header fails the build.
