"""A stock gRPC reflection client against a running learner: grpcio-reflection's
`ProtoReflectionDescriptorDatabase` (which speaks grpc.reflection.v1alpha) lists the services,
resolves `hybriddrive.v1.Learner` and its messages, and calls Status with messages built from the
reflected descriptors alone (no generated code of ours)."""

import grpc
from google.protobuf import descriptor_pool, message_factory
from grpc_reflection.v1alpha.proto_reflection_descriptor_database import ProtoReflectionDescriptorDatabase


def test_stock_reflection_client_lists_and_calls_the_learner(learner):
    with grpc.insecure_channel(learner.addr) as channel:
        db = ProtoReflectionDescriptorDatabase(channel)
        services = db.get_services()
        assert "hybriddrive.v1.Learner" in services, services
        assert "grpc.health.v1.Health" in services, services

        pool = descriptor_pool.DescriptorPool(db)
        service = pool.FindServiceByName("hybriddrive.v1.Learner")
        methods = {m.name for m in service.methods}
        assert {"Register", "StreamExperience", "GetWeights", "Status"} <= methods, methods

        status = service.methods_by_name["Status"]
        request_cls = message_factory.GetMessageClass(status.input_type)
        response_cls = message_factory.GetMessageClass(status.output_type)
        call = channel.unary_unary(
            f"/{service.full_name}/{status.name}",
            request_serializer=request_cls.SerializeToString,
            response_deserializer=response_cls.FromString,
        )
        reply = call(request_cls(), timeout=10)
        assert reply.run_id.startswith("run-"), reply
        assert reply.weights_version >= 1, reply
        # The status names the configured variant, read through reflected field names.
        assert reply.variant == "hybrid", reply
